"""Shared fixtures: composing configs the way `ccm run` does."""

from __future__ import annotations

from collections.abc import Callable, Iterator, Sequence

import pytest
from hydra import compose, initialize_config_dir
from omegaconf import DictConfig

from ccm.cli import config_dir


@pytest.fixture()
def composer() -> Iterator[Callable[[Sequence[str]], DictConfig]]:
    """``composer(overrides)`` -> the root config composed with those overrides."""
    with initialize_config_dir(str(config_dir()), version_base="1.3", job_name="test"):
        yield lambda overrides=(): compose("config", overrides=list(overrides))

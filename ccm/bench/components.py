"""The components a benchmark times, built as ``ccm run`` builds them."""

from __future__ import annotations

from collections.abc import Sequence
from typing import Any


def components(
    task: str, controller: str, sim: str | None = None, extra: Sequence[str] = ()
) -> Any:
    """Task, controller and simulator as ``ccm run`` builds them (``extra``: more overrides)."""
    from hydra import compose, initialize_config_dir

    from ccm.cli import config_dir
    from ccm.experiment.components import build_components

    with initialize_config_dir(str(config_dir()), version_base="1.3", job_name="bench"):
        overrides = [f"task={task}", f"controller={controller}"]
        overrides += ([f"sim={sim}"] if sim else []) + list(extra)
        cfg = compose("config", overrides=overrides)
    return build_components(cfg)

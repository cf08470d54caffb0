"""A run's condition configs from its own config, composing only where a condition changes
a config group (issue #40: Hydra composed 8-10 times per run, ~0.2 CPU-s each).

A condition (``experiment.conditions.<name>``) or a phase is a list of Hydra overrides on top
of the run's. Hydra composes a config in two steps: it merges the defaults list (the config
groups' chosen options), then applies the remaining ("config") overrides in order
(``ConfigLoaderImpl._apply_overrides_to_config``). When a condition's group overrides all
name the options the run already chose, the first step gives the run's merged config again,
so the condition's config is the run's config with the condition's value overrides applied by
that same Hydra function: :class:`Composer` does that on a copy. A condition that selects
another option of a group (``controller=avic_modes``) is composed in full, once per distinct
override list. ``tests/test_composer.py`` checks the two ways agree on every condition and
phase of every experiment config.
"""

from __future__ import annotations

import copy
from collections.abc import Callable, Mapping, Sequence
from typing import Any

from omegaconf import DictConfig, open_dict


class Composer:
    """``composer(extra)`` -> the config of the run's overrides plus ``extra``.

    Args:
        compose: ``compose(extra)``: Hydra's full compose of the run's overrides plus
            ``extra``, with its ``hydra`` node (:func:`ccm.experiment.precheck.compose_extra`).
        base: the run's composed config (no ``hydra`` node), never modified.
        choices: the run's config group choices (``hydra.runtime.choices``: group -> option).
    """

    def __init__(
        self,
        compose: Callable[[list[str]], DictConfig],
        base: DictConfig,
        choices: Mapping[str, Any],
    ) -> None:
        self._compose = compose
        self.base = base
        self.choices = {str(k): v for k, v in choices.items()}
        self._composed: dict[tuple[str, ...], DictConfig] = {}
        self.composes = 0  #: full composes made (the rest were derived from ``base``)

    def __call__(self, extra: Sequence[str]) -> DictConfig:
        return self.derive(extra)[0]

    def derive(self, extra: Sequence[str]) -> tuple[DictConfig, dict[str, Any]]:
        """(the config of the run's overrides plus ``extra``, its group choices)."""
        values = self.value_overrides(extra)
        if values is None:
            key = tuple(extra)
            if key not in self._composed:
                self.composes += 1
                self._composed[key] = self._compose(list(extra))
            full = self._composed[key]
            return job_config(full), dict(full.hydra.runtime.choices)
        from hydra._internal.config_loader_impl import ConfigLoaderImpl

        cfg = copy.deepcopy(self.base)
        ConfigLoaderImpl._apply_overrides_to_config(values, cfg)
        return cfg, dict(self.choices)

    def value_overrides(self, extra: Sequence[str]) -> list[Any] | None:
        """``extra`` parsed, without the group overrides that repeat the run's choices; None
        when one selects another option, adds or deletes a group, or names a package
        (``group@pkg=…``), or when a key is not under one of the config's top-level nodes:
        those need Hydra's full compose (which also gives their errors)."""
        from hydra.core.override_parser.overrides_parser import OverridesParser

        values = []
        for ov in OverridesParser.create().parse_overrides(list(extra)):
            key = ov.key_or_group
            if ov.package is not None or ov.is_hydra_override():
                return None
            if key in self.choices:
                if ov.is_delete() or ov.is_add() or ov.value() != self.choices[key]:
                    return None
                continue  # the option the run already has
            if "/" in key or key.split(".", 1)[0] not in self.base:
                return None
            values.append(ov)
        return values


def job_config(full: DictConfig) -> DictConfig:
    """A copy of a config composed with its ``hydra`` node, without it: what Hydra hands a
    job (``full`` is left as it is)."""
    cfg = copy.deepcopy(full)
    with open_dict(cfg):
        del cfg["hydra"]
    return cfg

"""Condition configs derived from the run's config (ccm/experiment/composer.py, issue #40)
equal Hydra's full compose on every condition and phase of every experiment config, and a
run composes in full only the conditions that change a config group."""

from __future__ import annotations

from collections.abc import Iterator

import pytest
from hydra import compose, initialize_config_dir
from omegaconf import OmegaConf

from ccm.cli import config_dir, group_options
from ccm.core.errors import to_plain
from ccm.experiment.composer import Composer, job_config
from ccm.experiment.precheck import compose_extra


@pytest.fixture(scope="module")
def hydra_ready() -> Iterator[None]:
    with initialize_config_dir(str(config_dir()), version_base="1.3", job_name="test"):
        yield


def _composer(base: list[str]) -> Composer:
    full = compose("config", overrides=base, return_hydra_config=True)
    return Composer(
        lambda x: compose_extra(base, x, dirs=[], hydra_node=True),
        job_config(full),
        full.hydra.runtime.choices,
    )


def _override_lists(cfg) -> list[list[str]]:  # noqa: ANN001
    """Every condition's overrides, and each phase's after its condition's."""
    conditions = to_plain(cfg.experiment.get("conditions")) or {}
    phases = to_plain(cfg.experiment.get("phases")) or []
    lists = [list(v) for v in conditions.values() if v is not None] or [[]]
    return [[*c, *p.get("overrides", [])] for c in lists for p in ([{"overrides": []}, *phases])]


def _text(cfg) -> str:  # noqa: ANN001
    return OmegaConf.to_yaml(cfg)  # interpolations as written: a resolved copy would hide one


@pytest.mark.parametrize("experiment", group_options("experiment"))
def test_derived_condition_configs_equal_a_full_compose(hydra_ready, experiment: str) -> None:
    base = [f"experiment={experiment}", "seed=7"]
    composer = _composer(base)
    for extra in _override_lists(composer.base):
        derived, choices = composer.derive(extra)
        full = compose_extra(base, extra, dirs=[], hydra_node=True)
        assert _text(derived) == _text(job_config(full)), extra
        assert choices == dict(full.hydra.runtime.choices), extra
        assert OmegaConf.is_struct(derived)


def test_only_a_group_change_is_composed_in_full(hydra_ready) -> None:
    composer = _composer(["experiment=h4_collisions"])
    assert composer.choices["controller"] == "avic_anticipation"
    same = composer(["controller=avic_anticipation", "controller.anticipation.k_collision=900"])
    assert composer.composes == 0
    assert same.controller.anticipation.k_collision == 900
    assert composer.base.controller.anticipation.k_collision != 900  # the run's is untouched
    other = composer(["controller=avic_modes"])
    again = composer(["controller=avic_modes"])
    assert composer.composes == 1 and other == again and other is not again
    assert "anticipation" not in other.controller
    for extra, why in (
        (["controller=avic_modes"], "another option"),
        (["+sim@extra=pymunk2d"], "a package"),
        (["~controller"], "a group deleted"),
        (["hydra.job.name=x"], "a hydra override"),
        (["+brand_new.key=1"], "no such top-level node"),
    ):
        assert composer.value_overrides(extra) is None, why
    assert [o.input_line for o in composer.value_overrides(["seed=3", "task=h4_collisions"])] == [
        "seed=3"
    ]


def test_a_bad_value_in_a_derived_condition_is_hydras_error(hydra_ready) -> None:
    from hydra.errors import ConfigCompositionException

    composer = _composer(["experiment=smoke"])
    with pytest.raises(ConfigCompositionException, match="no_such_key"):
        composer(["controller.no_such_key=1"])

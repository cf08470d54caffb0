"""The ``gp_contact_models`` analysis (seed B §5.3, Fig. 5) through ``run_experiment``.

The shipped settings restricted to the autonomous cases at 45 N/mm (fixed and varying wall)
take a few seconds. Tolerances come from seeds 0-7 of the full configuration: the contact
position error was +0.03 to +0.05 mm, the stiffness ratio 1.09 to 1.18 (a one-physics-step
lag between the sensed force and the recorded position steepens the slope), the predictive
std near contact 0.29-0.33 N for the fixed wall and 2.1-4.1 N for the varying one.
"""

from __future__ import annotations

from collections.abc import Callable, Iterator, Sequence
from pathlib import Path
from typing import Any

import pytest
from hydra import compose, initialize_config_dir
from omegaconf import DictConfig

from ccm.analyses.dispatch import run as run_experiment
from ccm.cli import config_dir
from ccm.core.errors import ConfigError
from ccm.reporting.load import load_run

BASE = [
    "experiment=gp_contact_models",
    "gp_contact.guidance=[autonomous]",
    "gp_contact.stiffnesses_Npm=[45000.0]",
]
TINY = [
    *BASE,
    "gp_contact.positions=[fixed]",
    "gp_contact.duration_s=2.0",
    "gp_contact.gp.max_points=80",
    "gp_contact.gp.n_restarts=0",
    "experiment.figures=false",
]


@pytest.fixture(scope="module")
def composer() -> Iterator[Callable[[Sequence[str]], DictConfig]]:
    with initialize_config_dir(str(config_dir()), version_base="1.3", job_name="test"):
        yield lambda overrides=(): compose("config", overrides=list(overrides))


def run(composer: Callable, out: Path, overrides: Sequence[str]) -> dict[str, Any]:
    cfg = composer(overrides)
    return run_experiment(cfg, lambda extra: composer([*overrides, *extra]), out)


@pytest.fixture(scope="module")
def fixed_and_varying(composer, tmp_path_factory) -> tuple[Path, dict[str, Any]]:
    out = tmp_path_factory.mktemp("gp_contact")
    return out, run(composer, out, BASE)


def test_autonomous_fixed_contact_is_identified(fixed_and_varying) -> None:
    out, summary = fixed_and_varying
    assert summary["status"] == "ok"
    m = summary["conditions"]["autonomous_fixed_45"]
    assert m["contact_position_true_m"] == 0.3 and m["stiffness_true_Npm"] == 45e3
    # 0.5 mm: better than the 0.33 mm the 15 N press sinks into the wall, plus margin
    assert abs(m["contact_position_error_m"]) < 5e-4, m["contact_position_error_m"]
    assert m["stiffness_ratio"] == pytest.approx(1.0, abs=0.3), m["stiffness_ratio"]
    for name in ("figures/gp_contact_models.png", "gp_contact_models.md"):
        assert (out / name).is_file(), name
    # experiment.timeseries = first_last: demonstrations 1 and 3 of each case, as Parquet
    files = sorted(p.relative_to(out).as_posix() for p in out.glob("timeseries/*/*.parquet"))
    assert files == [f"timeseries/{c}/trial_00{j}.parquet" for c in
                     ("autonomous_fixed_45", "autonomous_varying_45") for j in (1, 3)]  # fmt: skip
    series = load_run(out).timeseries
    assert {"condition", "trial", "t", "pos_x", "force_x"} <= set(series.columns)
    assert [t["trial"] for t in summary["trials"]] == [1, 2, 3, 1, 2, 3]


def test_varying_contact_position_raises_the_predictive_std(fixed_and_varying) -> None:
    c = fixed_and_varying[1]["conditions"]
    fixed, varying = c["autonomous_fixed_45"], c["autonomous_varying_45"]
    assert varying["contact_position_spread_m"] > 0.0 == fixed["contact_position_spread_m"]
    # measured ratio 7.2-12.9 over seeds 0-7; 3x leaves room yet fails if the effect is gone
    assert varying["pred_std_contact_N"] > 3.0 * fixed["pred_std_contact_N"]
    # the variance the MPC uses (tied σ_n², Eq. 1-2 as printed; issue #37) is below the
    # predictive std, which adds the noise once more, and rises with the spread too (seed 100:
    # 0.023 fixed, 0.73 N varying)
    assert varying["mpc_std_contact_N"] > 3.0 * fixed["mpc_std_contact_N"]
    for case in (fixed, varying):
        assert case["mpc_std_contact_N"] < case["pred_std_contact_N"]


def test_same_config_and_seed_give_identical_summaries(composer, tmp_path: Path) -> None:
    run(composer, tmp_path / "a", [*TINY, "seed=3"])
    run(composer, tmp_path / "b", [*TINY, "seed=3"])
    a, b = ((tmp_path / d / "summary.json").read_bytes() for d in "ab")
    assert a == b
    run(composer, tmp_path / "c", [*TINY, "seed=4"])
    assert (tmp_path / "c" / "summary.json").read_bytes() != a, "the seed matters"


@pytest.mark.parametrize(
    ("override", "key"),
    [
        ("+gp_contact.bogus=1", "gp_contact.bogus"),
        ("+gp_contact.human.bogus=1", "gp_contact.human.bogus"),
        ("gp_contact.guidance=[robot]", "gp_contact.guidance[0]"),
        ("gp_contact.gp.length_scale_bounds=[1.0,0.1]", "gp_contact.gp.length_scale_bounds"),
        ("gp_contact.record_hz=300.0", "gp_contact.record_hz"),
        ("gp_contact.gp.mpc_variance=shared", "gp_contact.gp.mpc_variance"),
    ],
)
def test_bad_config_names_the_key(composer, tmp_path: Path, override: str, key: str) -> None:
    with pytest.raises(ConfigError) as err:
        run(composer, tmp_path, [*BASE, override])
    assert err.value.key == key
    assert not (tmp_path / "summary.json").exists()

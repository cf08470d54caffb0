"""Trial time series on disk (issue #19): Parquet round trip, ``experiment.timeseries``
(which trials are written, validation), ``load_run`` on a real run, and the rail figure
reading the Parquet files back."""

from __future__ import annotations

import subprocess
import sys
from pathlib import Path
from typing import Any

import numpy as np
import pytest

from ccm.core.errors import ConfigError
from ccm.core.timeseries import (
    check_bits,
    keep_trial,
    read_timeseries,
    round_mantissa,
    trial_path,
    write_timeseries,
)
from ccm.experiment.components import check_experiment
from ccm.experiment.runner import run_experiment
from ccm.plots.rail import write_rail_figure
from ccm.reporting.load import load_run

CCM = str(Path(sys.executable).parent / "ccm")
#: a quick smoke run: two conditions, trials of 0.05 s, no figures
QUICK = ["experiment=smoke", "experiment.max_time_s=0.05", "experiment.figures=false"]


def _run(composer, tmp_path: Path, *overrides: str) -> dict[str, Any]:
    args = [*QUICK, *overrides]
    return run_experiment(composer(args), lambda extra: composer([*args, *extra]), tmp_path, False)


def _files(run: Path) -> set[tuple[str, int]]:
    return {
        (p.parent.name, int(p.stem.split("_")[1]))
        for p in (run / "timeseries").rglob("trial_*.parquet")
    }


def test_parquet_round_trip_keeps_columns_dtypes_and_values(tmp_path: Path) -> None:
    rng = np.random.default_rng(0)
    n = 1000
    table = {
        "t": np.arange(n) * 1e-3 + 100.0,  # float32 would not resolve 1 ms steps exactly here
        "pos_x": rng.normal(0.3, 0.1, n),
        "force_y": rng.normal(0.0, 20.0, n),
        "stiffness_Npm": np.full(n, 3000.0),
        "pred_rmse_N": np.where(np.arange(n) < 10, np.nan, 1.0),  # NaN before a model exists
    }
    path = trial_path(tmp_path, "cond", 7)
    assert path == tmp_path / "timeseries" / "cond" / "trial_007.parquet"
    write_timeseries(path, table)
    back = read_timeseries(path)
    assert list(back) == list(table)
    assert back["t"].dtype == np.float64
    np.testing.assert_array_equal(back["t"], table["t"])
    for name in list(table)[1:]:
        assert back[name].dtype == np.float32, name
        np.testing.assert_allclose(back[name], table[name], rtol=1e-7, atol=0, err_msg=name)
    assert np.isnan(back["pred_rmse_N"][:10]).all()
    assert not list(tmp_path.rglob("*.tmp"))  # written through a rename


@pytest.mark.parametrize("bits", [23, 18, 12, 8])
def test_rounded_mantissa_is_within_half_a_step_and_keeps_specials(bits: int) -> None:
    rng = np.random.default_rng(1)
    x = np.concatenate([rng.normal(0.0, 50.0, 5000), rng.normal(0.0, 1e-4, 5000)])
    x32 = x.astype(np.float32)
    r = round_mantissa(x32, bits)
    assert r.dtype == np.float32
    rel = np.abs(r.astype(np.float64) - x32) / np.abs(x32.astype(np.float64))
    assert rel.max() <= 2.0 ** -(bits + 1)
    if bits < 23:  # rounded, not truncated: the mean error is ~0, the mean |error| ~ a quarter step
        assert rel.mean() > 2.0 ** -(bits + 3)
        assert (r.view(np.uint32) & np.uint32((1 << (23 - bits)) - 1) == 0).all()
    else:
        np.testing.assert_array_equal(r, x32)
    special = np.array([np.nan, np.inf, -np.inf, 0.0, -0.0, 3.0, 255.0], dtype=np.float32)
    out = round_mantissa(special, bits)
    assert np.isnan(out[0]) and list(out[1:3]) == [np.inf, -np.inf]
    np.testing.assert_array_equal(out[3:], special[3:])  # small integers are exact


def test_fewer_bits_make_smaller_files_of_noisy_data(tmp_path: Path) -> None:
    rng = np.random.default_rng(2)
    table = {"t": np.arange(20000) * 1e-3, "force_x": rng.normal(5.0, 0.05, 20000)}
    sizes = {}
    for bits in (23, 18):
        write_timeseries(tmp_path / f"{bits}.parquet", table, bits)
        sizes[bits] = (tmp_path / f"{bits}.parquet").stat().st_size
        back = read_timeseries(tmp_path / f"{bits}.parquet")["force_x"]
        np.testing.assert_allclose(back, table["force_x"], rtol=2.0 ** -(bits + 1) + 6e-8)
    assert sizes[18] < 0.85 * sizes[23], sizes


@pytest.mark.parametrize("value", [0, 7, 24, 18.5, "18", True, None])
def test_timeseries_bits_out_of_range_is_a_one_line_error(value: Any) -> None:
    with pytest.raises(
        ConfigError, match=r"^experiment\.timeseries_bits: must be an integer from 8 to 23"
    ):
        check_bits(value)


def test_keep_trial_policy() -> None:
    assert [keep_trial("all", i, 4) for i in range(4)] == [True] * 4
    assert [keep_trial("first_last", i, 4) for i in range(4)] == [True, False, False, True]
    assert keep_trial("first_last", 0, 1)
    assert not any(keep_trial("none", i, 4) for i in range(4))


def test_first_last_keeps_the_first_and_last_trial_of_each_condition_and_phase(
    composer, tmp_path: Path
) -> None:
    phases = ("experiment.phases=[{name: train, trials: 4, overrides: []},"
              " {name: test, trials: 3, overrides: []}]")  # fmt: skip
    summary = _run(composer, tmp_path, phases, "experiment.timeseries=first_last")
    assert len(summary["trials"]) == 2 * 7
    # train is trials 1-4, test 5-7 (numbered across phases)
    expected = {(c, k) for c in ("fixed_low", "fixed_high") for k in (1, 4, 5, 7)}
    assert _files(tmp_path) == expected


def test_all_is_every_trial_and_first_last_is_the_default(composer, tmp_path: Path) -> None:
    _run(composer, tmp_path / "all", "experiment.trials=3", "experiment.timeseries=all")
    assert _files(tmp_path / "all") == {
        (c, k) for c in ("fixed_low", "fixed_high") for k in (1, 2, 3)
    }
    _run(composer, tmp_path / "default", "experiment.trials=3")
    assert _files(tmp_path / "default") == {
        (c, k) for c in ("fixed_low", "fixed_high") for k in (1, 3)
    }


def test_none_writes_no_timeseries(composer, tmp_path: Path) -> None:
    summary = _run(composer, tmp_path, "experiment.timeseries=none")
    assert summary["status"] == "ok" and len(summary["trials"]) == 4
    assert not (tmp_path / "timeseries").exists()


def test_a_bad_timeseries_value_is_a_one_line_error(composer, tmp_path: Path) -> None:
    with pytest.raises(ConfigError, match=r"experiment\.timeseries.*all, first_last, none"):
        check_experiment(composer([*QUICK, "experiment.timeseries=some"]))
    res = subprocess.run(
        [CCM, "run", *QUICK, "experiment.timeseries=every", f"hydra.run.dir={tmp_path / 'r'}"],
        cwd=tmp_path, capture_output=True, text=True, timeout=120, check=False,
    )  # fmt: skip
    assert res.returncode != 0
    assert "Traceback" not in res.stderr
    lines = [ln for ln in res.stderr.splitlines() if ln.startswith("ccm:")]
    assert lines == [
        "ccm: error: experiment.timeseries: unknown value 'every'; allowed: all, first_last, none"
    ], res.stderr


def test_load_run_on_a_small_run(composer, tmp_path: Path) -> None:
    summary = _run(composer, tmp_path, "experiment.trials=3")
    run = load_run(tmp_path)
    assert run.summary == summary
    assert list(run.conditions.index) == ["fixed_low", "fixed_high"]
    assert run.conditions.loc["fixed_high", "rms_tracking_error_m"] == pytest.approx(
        summary["conditions"]["fixed_high"]["rms_tracking_error_m"]
    )
    assert len(run.trials) == 6
    assert set(run.trials.columns) >= {"condition", "phase", "trial", "seed", "peak_force_N"}
    ts = run.timeseries
    assert list(ts.columns[:4]) == ["condition", "phase", "trial", "t"]
    keys = set(ts[["condition", "trial"]].itertuples(index=False, name=None))
    assert keys == {(c, k) for c in ("fixed_low", "fixed_high") for k in (1, 3)}
    assert set(ts["phase"]) == {"main"}
    one = ts[(ts["condition"] == "fixed_low") & (ts["trial"] == 3)]
    np.testing.assert_array_equal(one["t"].to_numpy(), np.arange(len(one)) * one["t"].iloc[1])
    assert load_run(tmp_path, timeseries=False).timeseries.empty


def test_load_run_needs_a_summary(tmp_path: Path) -> None:
    with pytest.raises(FileNotFoundError, match="holds no summary.json"):
        load_run(tmp_path)
    with pytest.raises(FileNotFoundError, match="does not exist"):
        load_run(tmp_path / "missing")


def test_rail_figure_reads_the_parquet_files(tmp_path: Path) -> None:
    """Every non-demonstration trial with a file is one line per axis; a trial without a file
    (first_last dropped it) is left out."""
    params = {"rail_point": [0.0, 0.10], "rail_normal": [0.0, -1.0], "tool_half_extent_m": 0.0}
    n = 200
    for trial in (1, 2, 3):
        write_timeseries(trial_path(tmp_path, "variance_cost", trial), {
            "t": np.arange(n) * 1e-3, "pos_x": np.zeros(n), "pos_y": np.linspace(0.0, 0.1, n),
            "damping_x_Nspm": np.full(n, 100.0 * trial), "damping_y_Nspm": np.full(n, 500.0),
        })  # fmt: skip
    trials = [{"condition": "variance_cost", "trial": k, "phase": p}
              for k, p in ((1, "demo_left"), (2, "autonomous"), (3, "execution"),
                           (4, "execution"))]  # fmt: skip
    saved: dict[str, Any] = {}

    def save(fig: Any, name: str) -> None:
        saved[name] = [[line.get_ydata()[0] for line in ax.get_lines()] for ax in fig.axes]
        fig.savefig(tmp_path / name)

    write_rail_figure(tmp_path, trials, 2, params, save)
    # per axis: trials 2 and 3 (trial 1 is a demonstration, trial 4 has no file), then the
    # contact line at 0
    (d_x, d_y) = saved["mpc_rail_damping.png"]
    assert d_x[:2] == [200.0, 300.0] and len(d_x) == 3
    assert d_y[:2] == [500.0, 500.0] and len(d_y) == 3
    assert (tmp_path / "mpc_rail_damping.png").stat().st_size > 0

"""The `ccm` console script as a user runs it: from another directory, in a subprocess."""

from __future__ import annotations

import json
import subprocess
import sys
from pathlib import Path

import pytest

from ccm.core.timeseries import read_timeseries, trial_path
from ccm.metrics.trial import BASE_METRICS

CCM = str(Path(sys.executable).parent / "ccm")


def ccm(args: list[str], cwd: Path) -> subprocess.CompletedProcess[str]:
    return subprocess.run(
        [CCM, *args], cwd=cwd, capture_output=True, text=True, timeout=120, check=False
    )


def run_dirs(root: Path) -> list[Path]:
    return sorted(p.parent.parent for p in root.rglob(".hydra/config.yaml"))


def test_smoke_run_writes_a_complete_run_directory(tmp_path: Path) -> None:
    res = ccm(["run", "experiment=smoke"], tmp_path)
    assert res.returncode == 0, res.stderr
    (run,) = run_dirs(tmp_path / "outputs")
    assert len(list((run / "figures").glob("*.png"))) >= 4
    for name in ("config.yaml", "overrides.yaml", "hydra.yaml"):
        assert (run / ".hydra" / name).is_file()
    summary = json.loads((run / "summary.json").read_text())
    assert summary["status"] == "ok"
    assert summary["experiment"] == "smoke"
    assert set(summary["conditions"]) == {"fixed_low", "fixed_high"}
    for metrics in summary["conditions"].values():
        assert set(BASE_METRICS) <= set(metrics)
    assert len(summary["trials"]) == 4  # 2 conditions x 2 trials
    for cond in ("fixed_low", "fixed_high"):
        for trial in (1, 2):
            header = read_timeseries(trial_path(run, cond, trial))
            for col in (
                "t",
                "target_pos_x",
                "pos_x",
                "vel_x",
                "force_x",
                "cmd_force_x",
                "stiffness_Npm",
            ):
                assert col in header
    # the stiff controller tracks better than the soft one against the same spring
    c = summary["conditions"]
    assert c["fixed_high"]["rms_tracking_error_m"] < c["fixed_low"]["rms_tracking_error_m"]


def test_same_seed_gives_identical_summary(tmp_path: Path) -> None:
    for _ in range(2):
        assert (
            ccm(["run", "experiment=smoke", "sim.sensor.force_noise_std=0.3"], tmp_path).returncode
            == 0
        )
    a, b = (p / "summary.json" for p in run_dirs(tmp_path / "outputs"))
    assert a.read_bytes() == b.read_bytes()
    other = tmp_path / "other"
    other.mkdir()
    assert (
        ccm(
            ["run", "experiment=smoke", "sim.sensor.force_noise_std=0.3", "seed=1"], other
        ).returncode
        == 0
    )
    (c,) = (p / "summary.json" for p in run_dirs(other / "outputs"))
    assert c.read_bytes() != a.read_bytes()


@pytest.mark.parametrize(
    ("override", "expected"),
    [
        (
            "controller=nope",
            "controller=nope: unknown option; allowed: aic, avic,",
        ),
        ("controller.stiffness=-5", "controller.stiffness: must be > 0"),
        ("sim.dt=0", "sim.dt: must be > 0"),
        ("task=nope", "task=nope: unknown option; allowed:"),
        ("experiment=nope", "experiment=nope: unknown option; allowed:"),
        ("sim=nope", "sim=nope: unknown option; allowed: mujoco3d, pybullet3d, pymunk2d"),
        ("controller.stifness=3", "controller.stifness: unknown key"),
        ("controller.stiffness=nan", "controller.stiffness: must be a finite number"),
        ("sim.control_decimation=0", "sim.control_decimation: must be an integer >= 1"),
        ("experiment.trials=-1", "experiment.trials: must be an integer >= 1"),
        ("seed=abc", "seed: must be an integer"),
        ("task.pattern=[]", "task.pattern: must contain at least one segment"),
        (
            "controller.loop.damping_rule=magic",
            "controller.loop.damping_rule: unknown value 'magic'",
        ),
    ],
)
def test_bad_override_is_one_line_and_nonzero(tmp_path: Path, override: str, expected: str) -> None:
    res = ccm(["run", override], tmp_path)
    assert res.returncode == 2
    lines = res.stderr.strip().splitlines()
    assert len(lines) == 1, res.stderr
    assert expected in lines[0]
    assert "Traceback" not in res.stderr
    # nothing claims success: the check happens before any run directory exists
    assert not list(tmp_path.rglob("summary.json"))


def test_diverging_simulation_marks_the_run_failed(tmp_path: Path) -> None:
    res = ccm(["run", "experiment=smoke", "sim.max_speed=0.01"], tmp_path)
    assert res.returncode == 1
    assert len(res.stderr.strip().splitlines()) == 1
    assert "sim.max_speed" in res.stderr
    (run,) = run_dirs(tmp_path / "outputs")
    summary = json.loads((run / "summary.json").read_text())
    assert summary["status"] == "failed"
    assert "exceeds sim.max_speed" in summary["error"]


def test_multirun_sweep(tmp_path: Path) -> None:
    res = ccm(["run", "-m", "experiment=smoke", "seed=0,1", "experiment.fast=true"], tmp_path)
    assert res.returncode == 0, res.stderr
    runs = run_dirs(tmp_path / "multirun")
    assert len(runs) == 2
    seeds = sorted(json.loads((r / "summary.json").read_text())["seed"] for r in runs)
    assert seeds == [0, 1]


def test_sweep_value_is_checked_too(tmp_path: Path) -> None:
    res = ccm(["run", "-m", "controller=fixed_impedance,nope"], tmp_path)
    assert res.returncode == 2
    assert "controller=nope: unknown option" in res.stderr


def test_list_help_and_unknown_command(tmp_path: Path) -> None:
    res = ccm(["list"], tmp_path)
    assert res.returncode == 0
    for word in ("experiment:", "smoke", "multi_spring", "fixed_impedance_high", "pymunk2d"):
        assert word in res.stdout
    assert ccm(["--help"], tmp_path).returncode == 0
    res = ccm(["frobnicate"], tmp_path)
    assert res.returncode == 2
    assert "allowed: run, list" in res.stderr


_BLAS_PROBE = """
import json, sys
import ccm.experiment.runner
from threadpoolctl import threadpool_info
from ccm.cli import main

def probe(cfg, compose, out_dir, **kwargs):
    import scipy.linalg, scipy.optimize  # what a GP fit loads, if nothing has yet
    threads = [i["num_threads"] for i in threadpool_info() if i["internal_api"] == "openblas"]
    print("BLAS-THREADS", json.dumps(threads))
    return {"status": "ok", "conditions": {}, "trials": []}

ccm.experiment.runner.run_experiment = probe
sys.exit(main(["run", "experiment=smoke", "hydra.run.dir=" + sys.argv[1]]))
"""


def test_a_run_limits_every_blas_library_to_blas_threads(tmp_path: Path) -> None:
    """``blas_threads: 1`` reaches scipy's own OpenBLAS too (GP fits, L-BFGS-B), not only the
    libraries loaded when the limit was set: a multi-threaded GP fit on the 2-core machines
    ran ~5x slower, and parallel sweep workers would oversubscribe the cores."""
    out = subprocess.run(
        [sys.executable, "-c", _BLAS_PROBE, str(tmp_path / "run")],
        capture_output=True, text=True, timeout=300, check=False,
    )  # fmt: skip
    lines = [ln for ln in out.stdout.splitlines() if ln.startswith("BLAS-THREADS")]
    assert lines, out.stdout + out.stderr
    threads = json.loads(lines[0].split(" ", 1)[1])
    assert len(threads) >= 2, threads  # numpy's and scipy's OpenBLAS
    assert threads == [1] * len(threads)

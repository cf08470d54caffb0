"""Hostile input that once lost data or failed silently (issue #39 item 2): each case gets one
line naming the problem, a non-zero exit, and nothing already written is changed."""

from __future__ import annotations

import os
from collections.abc import Callable
from pathlib import Path

import pytest

from ccm.cli import config_dir, main


def _snapshot(root: Path) -> dict[str, bytes]:
    return {
        str(p.relative_to(root)): p.read_bytes() for p in sorted(root.rglob("*")) if p.is_file()
    }


def _existing_file(tmp: Path) -> list[str]:
    (tmp / "d.csv").write_text("t,x\n0,1\n")
    return ["demo", "smoke", "--out", str(tmp / "d.csv")]


def _directory(tmp: Path) -> list[str]:
    (tmp / "d.csv").mkdir()
    return ["demo", "smoke", "--out", str(tmp / "d.csv")]


def _under_a_file(tmp: Path) -> list[str]:
    (tmp / "f").write_text("x")
    return ["demo", "smoke", "--out", str(tmp / "f" / "d.csv")]


def _negative_seed(tmp: Path) -> list[str]:
    return ["demo", "smoke", "--out", str(tmp / "d.csv"), "--seed", "-1"]


def _unwritable(tmp: Path) -> list[str]:
    return ["demo", "smoke", "--out", "/proc/ccm-demo.csv"]  # read-only even for root


DEMO_CASES: dict[str, tuple[Callable[[Path], list[str]], str]] = {
    "existing file": (_existing_file, "d.csv exists; pass --force to replace it"),
    "directory": (_directory, "d.csv is a directory"),
    "parent is a file": (_under_a_file, "cannot write in"),
    "negative seed": (_negative_seed, "--seed: must be an integer >= 0, got -1"),
    "read-only place": (_unwritable, "/proc/ccm-demo.csv: cannot write"),
}


@pytest.mark.parametrize("case", list(DEMO_CASES))
def test_demo_refuses_with_one_line_and_overwrites_nothing(
    case: str, tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    make, expected = DEMO_CASES[case]
    argv = make(tmp_path)
    before = _snapshot(tmp_path)
    assert main(argv) == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and expected in err, err
    assert _snapshot(tmp_path) == before


def test_demo_force_replaces_an_existing_file(tmp_path: Path) -> None:
    out = tmp_path / "d.csv"
    out.write_text("t,x\n0,1\n")
    assert main(["demo", "smoke", "--out", str(out), "--force"]) == 0
    assert out.read_text().startswith("t,x,y,")
    assert [p.name for p in tmp_path.iterdir()] == ["d.csv"]  # no temporary file left


#: ``ccm run`` overrides that once ran and reported numbers that were not (issue #39), with
#: the key the one line must name and what it must say
SMOKE, SINGLE = "experiment=smoke", "experiment=single"
RUN_CASES = {
    "cut-off far below a trial": (
        [SMOKE, "metrics.lowpass_hz=1e-300"],
        "metrics.lowpass_hz: 1e-300 Hz: must lie in [0.265, 500) Hz",
    ),
    "cut-off above Nyquist": (
        [SMOKE, "metrics.lowpass_hz=1e9"],
        "metrics.lowpass_hz: 1e+09 Hz: must lie in [0.265, 500) Hz",
    ),
    "cut-off at Nyquist": ([SMOKE, "metrics.lowpass_hz=500"], "metrics.lowpass_hz: 500 Hz:"),
    "a trial that outgrows memory": (
        [SMOKE, "experiment.settle_time_s=1e7"],
        "experiment.settle_time_s: a trial of 1e+07 s is 10000000400 control steps",
    ),
    "noise beyond any sensor": (
        [SMOKE, "sim.sensor.force_noise_std=1e200"],
        "sim.sensor.force_noise_std: must lie within ±100000",
    ),
    "bias beyond any sensor": (
        [SMOKE, "sim.sensor.force_bias=-1e6"],
        "sim.sensor.force_bias: must lie within ±100000",
    ),
    "reference model beyond Nyquist": (
        [SINGLE, "controller=mrac", "controller.omega=1e200"],
        "controller.omega: must be <= pi / control step = 3142 rad/s",
    ),
}


def test_the_cut_off_bounds_follow_the_trial_and_the_step() -> None:
    """The bounds are the filter's physics: time constant 1/(2 pi f) within the trial, f below
    the Nyquist frequency 1/(2 dt); values just inside pass."""
    from ccm.core.errors import ConfigError
    from ccm.experiment.config_check import check_lowpass

    check_lowpass(1.0 / (2 * 3.141592653589793 * 2.0) * 1.001, 0.001, 2.0)
    check_lowpass(499.9, 0.001, 2.0)
    check_lowpass(249.9, 0.002, 2.0)
    for f, dt in ((250.0, 0.002), (0.079, 0.001)):
        with pytest.raises(ConfigError, match="metrics.lowpass_hz"):
            check_lowpass(f, dt, 2.0)


@pytest.mark.parametrize("fps", ["1e6", "0.5", "nan"])
def test_animate_refuses_a_frame_rate_outside_what_a_clip_holds(
    fps: str, tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    from ccm.core.errors import ConfigError
    from ccm.plots.frames import AnimateSettings

    with pytest.raises(ConfigError, match=r"--fps: must be (in \[1.0, 100.0\]|a finite)"):
        AnimateSettings.from_mapping({}, float(fps))
    AnimateSettings.from_mapping({}, 100.0)  # the GIF limit itself is allowed


def test_report_lists_a_string_metric_as_missing() -> None:
    from ccm.reporting.report import metrics_table

    runs = [
        (Path(f"r{i}"), {"experiment": "e", "seed": i, "status": "ok",
                         "conditions": {"c": {"m": v}}})
        for i, v in enumerate([1.0, "oops", 3.0])
    ]  # fmt: skip
    row = metrics_table(runs).iloc[0]
    assert (row["metric"], row["n"], row["missing"], row["mean"]) == ("m", 2, 1, 2.0)


TRUST_CASES = {
    "a callback calling open": (
        [SMOKE, "+hydra.callbacks.evil._target_=builtins.open", "+hydra.callbacks.evil.file=x"],
        "hydra.callbacks.evil._target_: 'builtins.open' is not one of ccm's or Hydra's own",
    ),
    "a callback nested in an allowed one": (
        [SMOKE, "+hydra.callbacks.sweep_check.hook._target_=shutil.copyfile"],
        "hydra.callbacks.sweep_check.hook._target_: 'shutil.copyfile' is not one of",
    ),
    "a logging handler that is a function": (
        [SMOKE, "hydra.job_logging.handlers.file.class=os.system"],
        "hydra.job_logging.handlers.file.class: 'os.system' is not one of",
    ),
    "an environment variable in an override": (
        [SMOKE, "task.name=${oc.env:HOME}"],
        "task.name: reads an environment variable (${oc.env:...})",
    ),
}


@pytest.mark.parametrize("case", [*RUN_CASES, *TRUST_CASES])
def test_run_refuses_with_one_line_and_writes_nothing(
    case: str, tmp_path: Path, capsys: pytest.CaptureFixture[str], monkeypatch: pytest.MonkeyPatch
) -> None:
    monkeypatch.delenv("HYDRA_FULL_ERROR", raising=False)
    overrides, expected = {**RUN_CASES, **TRUST_CASES}[case]
    out = tmp_path / "run"
    assert main(["run", *overrides, f"hydra.run.dir={out}"]) == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and err.startswith(f"ccm: error: {expected}"), err
    assert os.environ["HOME"] not in err  # no environment value reaches a message
    assert not out.exists()


def test_an_environment_variable_in_a_lab_config_is_refused(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    lab = tmp_path / "lab" / "task"
    lab.mkdir(parents=True)
    task = (config_dir() / "task" / "smoke.yaml").read_text(encoding="utf-8")
    (lab / "smoke.yaml").write_text(task.replace("name: smoke", "name: ${oc.env:HOME}", 1))
    out = tmp_path / "run"
    assert main(["run", "-cd", str(lab.parent), SMOKE, f"hydra.run.dir={out}"]) == 2
    err = capsys.readouterr().err
    assert err.startswith("ccm: error: task.name: reads an environment variable"), err
    assert os.environ["HOME"] not in err and not out.exists()


def test_only_ccms_hydras_and_loggings_callables_are_allowed() -> None:
    from ccm.experiment.trust import allowed_callable

    for name in (
        "ccm.experiment.sweep_check.SweepCheck",
        "hydra_plugins.hydra_joblib_launcher.joblib_launcher.JoblibLauncher",
        "hydra._internal.core_plugins.basic_sweeper.BasicSweeper",
        "logging.StreamHandler",
        "logging.handlers.RotatingFileHandler",
    ):
        assert allowed_callable(name), name
    for name in (
        "builtins.open", "shutil.copyfile", "os.system", "hydra.utils.call",
        "ccm.core.records.write_atomic", "logging.basicConfig", "logging.os",
    ):  # fmt: skip
        assert not allowed_callable(name), name


def test_report_on_a_binary_summary_names_it(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    """Issue #39: bytes that are not UTF-8 in summary.json raised UnicodeDecodeError."""
    (tmp_path / "run").mkdir()
    (tmp_path / "run" / "summary.json").write_bytes(bytes(range(128, 256)))
    assert main(["report", str(tmp_path)]) == 1  # a report of failed runs only: exit 1
    err = capsys.readouterr().err
    assert "Traceback" not in err and err.strip().splitlines()[-1].startswith(
        "ccm: error: report.dir: no usable run"
    )
    assert "unreadable" in (tmp_path / "report.md").read_text(encoding="utf-8")


@pytest.fixture(scope="module")
def smoke_run(tmp_path_factory: pytest.TempPathFactory) -> Path:
    out = tmp_path_factory.mktemp("smoke") / "run"
    assert main(["run", SMOKE, "experiment.figures=false", f"hydra.run.dir={out}"]) == 0
    return out


DAMAGE = {
    "truncated Parquet": ("timeseries/fixed_low/trial_002.parquet", "Parquet magic bytes"),
    "truncated summary.json": ("summary.json", "Unterminated string"),
    "truncated config": (".hydra/config.yaml", "config.yaml cannot be read"),
}


@pytest.mark.parametrize("case", list(DAMAGE))
def test_animate_names_a_damaged_file(
    case: str, smoke_run: Path, tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    import shutil

    run = tmp_path / "run"
    shutil.copytree(smoke_run, run)
    name, expected = DAMAGE[case]
    damaged = run / name
    damaged.write_bytes(damaged.read_bytes()[:100])
    before = _snapshot(run)
    assert main(["animate", str(run), "--out", str(tmp_path / "a.gif")]) == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and f"ccm: error: RUN_DIR: {damaged}" in err, err
    assert expected in err and "the run's record is damaged" in err
    assert _snapshot(run) == before and not (tmp_path / "a.gif").exists()


def _recording(tmp: Path, kind: str) -> Path:
    """A demonstration file of ``kind``: a directory, a FIFO, t in ms, t as datetimes."""
    import numpy as np
    import pandas as pd

    path = tmp / "demo.csv"
    if kind == "directory":
        path.mkdir()
    elif kind == "fifo":
        os.mkfifo(path)
    else:
        n = 3000
        t = np.arange(n) * 1e-3
        x = np.linspace(0.0, 0.05, n)
        col = (
            t * 1e3
            if kind == "milliseconds"
            else pd.date_range("2026-01-01", periods=n, freq="1ms")
        )
        pd.DataFrame({"t": col, "x": x, "y": 0.0}).to_csv(path, index=False)
    return path


RECORDINGS = {
    "directory": "demo.csv: is a directory, not a file",
    "fifo": "demo.csv: is not a regular file (a FIFO, socket or device)",
    "milliseconds": (
        "column t steps by 1 s (median); a recording is sampled every 1e-05 to 0.1 s "
        "(milliseconds? t is in seconds)"
    ),
    "datetimes": (
        "row 1: column t is not a finite number (seconds from the start, not a date or clock time)"
    ),
}


@pytest.mark.parametrize("kind", list(RECORDINGS))
def test_a_recording_that_is_not_one_is_named(
    kind: str, tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    path = _recording(tmp_path, kind)
    pattern = f"task.pattern=[{{type: recording, file: '{path}'}}]"
    out = tmp_path / "run"
    assert main(["run", SINGLE, "task=smoke", pattern, f"hydra.run.dir={out}"]) == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and RECORDINGS[kind] in err, err
    assert err.startswith(f"ccm: error: task.pattern[0].file: {path}")
    assert not out.exists()


def test_a_full_disk_while_writing_the_record_is_one_line(
    tmp_path: Path, capsys: pytest.CaptureFixture[str], monkeypatch: pytest.MonkeyPatch
) -> None:
    import errno

    import ccm.experiment.run_record as run_record

    def full(path: Path, text: str) -> None:
        raise OSError(errno.ENOSPC, os.strerror(errno.ENOSPC), str(path))

    monkeypatch.setattr(run_record, "write_atomic", full)
    out = tmp_path / "run"
    with pytest.raises(SystemExit) as stop:  # inside the Hydra job: exits as ccm run does
        main(["run", SMOKE, f"hydra.run.dir={out}"])
    assert stop.value.code == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and err.startswith(
        f"ccm: error: run directory {out}: cannot write its record (No space left on device)"
    ), err
    assert not (out / "summary.json").exists()

"""Run records a lab can trust (issue #19): the run directory's lock, the config check and
``--force``, clean interrupts (SIGINT, SIGTERM; a local sweep's workers stopped too).

The lock and interrupt cases run real ``ccm run`` subprocesses lasting several seconds; the
config check runs in-process (``ccm.cli.main``, as the reliability catalogue does). The resume
test with the local launcher and stale temporary files is in tests/test_resume.py.
"""

from __future__ import annotations

import fcntl
import json
import os
import re
import signal
import subprocess
import sys
import time
from pathlib import Path
from typing import Any

import pytest
import yaml

import ccm.cli as cli
from ccm.experiment.run_record import (
    RecordRefused,
    RunLock,
    clean_stale_temp,
    config_digest,
    open_record,
)

NOISE = (re.compile(r"^pybullet build time:"),)
FAST = ["experiment.fast=true", "experiment.figures=false"]


def _env() -> dict[str, str]:
    env = {k: v for k, v in os.environ.items() if k != "HYDRA_FULL_ERROR"}
    env["TQDM_DISABLE"] = "1"  # no progress bar lines on stderr
    return env


def _start(args: list[str], cwd: Path) -> subprocess.Popen[str]:
    return subprocess.Popen(
        [sys.executable, "-m", "ccm.cli", *args], cwd=cwd, env=_env(), text=True,
        stdout=subprocess.PIPE, stderr=subprocess.PIPE, start_new_session=True,
    )  # fmt: skip


def _lines(text: str) -> list[str]:
    return [ln for ln in text.splitlines() if ln.strip() and not any(p.match(ln) for p in NOISE)]


def _wait_for(predicate, timeout: float = 120.0) -> None:  # noqa: ANN001
    t0 = time.monotonic()
    while not predicate():
        assert time.monotonic() - t0 < timeout, "timed out"
        time.sleep(0.05)


def _snapshot(root: Path) -> dict[str, bytes]:
    return {
        str(p.relative_to(root)): p.read_bytes() for p in sorted(root.rglob("*")) if p.is_file()
    }


# --- 1. the lock --------------------------------------------------------------------------


def test_two_concurrent_runs_into_one_directory(tmp_path: Path) -> None:
    """The issue's case: a run, and 0.5 s later another config into the same directory, each
    of several seconds. One runs, the other is refused in one line and writes nothing."""
    run = tmp_path / "x"
    common = ["experiment.figures=false", "experiment.timeseries=all", f"hydra.run.dir={run}"]
    first = ["run", "experiment=single", "experiment.trials=150", "controller.stiffness=300",
             *common]  # fmt: skip
    second = ["run", "experiment=single", "experiment.trials=100", "controller.stiffness=3000",
              *common]  # fmt: skip
    a = _start(first, tmp_path)
    time.sleep(0.5)
    b = _start(second, tmp_path)
    (_, a_err), (_, b_err) = a.communicate(timeout=600), b.communicate(timeout=600)
    results = {a.pid: (a, a_err, 150, 300.0), b.pid: (b, b_err, 100, 3000.0)}
    winners = [r for r in results.values() if r[0].returncode == 0]
    losers = [r for r in results.values() if r[0].returncode != 0]
    assert len(winners) == 1 and len(losers) == 1, (a_err, b_err)
    (winner, _, trials, stiffness), (loser, loser_err, _, _) = winners[0], losers[0]
    assert loser.returncode == cli.EXIT_CONFIG
    assert "Traceback" not in loser_err
    (line,) = _lines(loser_err)
    assert line == (
        f"ccm: error: run directory {run} is in use by another run (pid {winner.pid}); "
        "wait for it to end or choose another directory"
    )
    # the record is the winner's alone: config, summary, every trial's time series
    summary = json.loads((run / "summary.json").read_text())
    assert summary["status"] == "ok" and len(summary["trials"]) == trials
    assert len(list((run / "timeseries").rglob("*.parquet"))) == trials
    config = yaml.safe_load((run / ".hydra" / "config.yaml").read_text())
    assert config["controller"]["stiffness"] == stiffness
    assert config["experiment"]["trials"] == trials
    assert f"controller.stiffness={stiffness:g}" in (run / ".hydra" / "overrides.yaml").read_text()
    assert summary["conditions"]["fixed_impedance"]["mean_stiffness_Npm"] == stiffness
    assert not (run / ".lock").exists()


def test_lock_is_exclusive_names_the_holder_and_is_removed(tmp_path: Path) -> None:
    lock = RunLock(tmp_path)
    lock.acquire()
    assert (tmp_path / ".lock").read_text() == f"{os.getpid()}\n"
    with pytest.raises(RecordRefused, match=rf"is in use by another run \(pid {os.getpid()}\)"):
        RunLock(tmp_path).acquire()  # another open file description: flock says no
    lock.release()
    assert not (tmp_path / ".lock").exists()
    (tmp_path / ".lock").write_text("12345\n")  # left by a killed run: not locked any more
    again = RunLock(tmp_path)
    again.acquire()
    again.release()


def test_a_refused_run_writes_nothing(tmp_path: Path) -> None:
    with open(tmp_path / ".lock", "w") as held:  # another process's lock, as flock sees it
        fcntl.flock(held, fcntl.LOCK_EX)
        held.write("4242\n")
        held.flush()
        before = _snapshot(tmp_path)
        res = subprocess.run(
            [sys.executable, "-m", "ccm.cli", "run", "experiment=smoke", *FAST,
             f"hydra.run.dir={tmp_path}"],
            env=_env(), capture_output=True, text=True, timeout=300, check=False,
        )  # fmt: skip
        assert res.returncode == cli.EXIT_CONFIG
        assert _lines(res.stderr) == [
            f"ccm: error: run directory {tmp_path} is in use by another run (pid 4242); "
            "wait for it to end or choose another directory"
        ]
        after = _snapshot(tmp_path)
    after.pop("cli.log", None)  # Hydra's (empty) job log, opened before any ccm code runs
    assert after == before  # no .hydra/, summary, time series or config hash


# --- 2. the config hash -------------------------------------------------------------------


@pytest.fixture
def in_process(monkeypatch: pytest.MonkeyPatch, capsys: pytest.CaptureFixture[str]):  # noqa: ANN201
    """``run(args) -> (exit code, stdout, stderr)`` through ``ccm.cli.main``."""
    monkeypatch.delenv("HYDRA_FULL_ERROR", raising=False)

    def run(args: list[str]) -> tuple[int, str, str]:
        try:
            code = cli.main(args)
        except SystemExit as exc:
            code = exc.code if isinstance(exc.code, int) else 1
        cap = capsys.readouterr()
        return code, cap.out, cap.err

    return run


def test_another_config_is_refused_and_force_moves_the_old_record_aside(
    tmp_path: Path, in_process
) -> None:  # noqa: ANN001
    run = tmp_path / "run"
    base = ["run", "experiment=smoke", *FAST, f"hydra.run.dir={run}"]
    code, _, err = in_process(base)
    assert code == 0, err
    first = _snapshot(run)
    assert "already ok" in in_process(base)[1]  # the same config: resumed (skipped)

    code, out, err = in_process([*base, "controller.stiffness=500"])
    assert code == cli.EXIT_CONFIG
    assert _lines(err) == [
        f"ccm: error: run directory {run} holds a run of another config (config.sha256 "
        "differs); run again with --force to move it aside and start over, or choose another "
        "directory"
    ]
    assert _snapshot(run) == first  # .hydra/config.yaml included: nothing overwritten
    digest = (run / "config.sha256").read_text().strip()

    code, out, err = in_process(["run", "--force", *base[1:], "controller.stiffness=500"])
    assert code == 0, err
    (aside,) = tmp_path.glob("run.replaced-*")
    assert f"moved aside -> {aside}" in out
    assert _snapshot(aside) == first  # the old record, whole
    assert (run / "config.sha256").read_text().strip() != digest
    assert (
        yaml.safe_load((run / ".hydra" / "config.yaml").read_text())["controller"]["stiffness"]
        == 500
    )
    assert json.loads((run / "summary.json").read_text())["status"] == "ok"


def test_a_folder_ccm_did_not_make_is_refused_and_force_moves_it_aside(
    tmp_path: Path, in_process
) -> None:  # noqa: ANN001
    """Issue #39: a run into an existing folder holding someone's summary.json and figures/
    overwrote them and exited 0; now it is refused with one line, and --force moves it aside."""
    run = tmp_path / "theirs"
    (run / "figures").mkdir(parents=True)
    (run / "summary.json").write_text('{"mine": 1}\n')
    (run / "figures" / "plot.png").write_bytes(b"not ccm's")
    mine = _snapshot(run)
    base = ["run", "experiment=smoke", *FAST, f"hydra.run.dir={run}"]
    code, _, err = in_process(base)
    assert code == cli.EXIT_CONFIG
    assert _lines(err) == [
        f"ccm: error: run directory {run} holds files that are not a ccm run record (figures, "
        "summary.json); run again with --force to move it aside and start over, or choose "
        "another directory"
    ]
    after = _snapshot(run)
    after.pop("cli.log", None)  # Hydra's job log, opened before any ccm code runs
    assert after == mine

    code, out, err = in_process(["run", "--force", *base[1:]])
    assert code == 0, err
    (aside,) = tmp_path.glob("theirs.replaced-*")
    assert f"moved aside -> {aside}" in out
    kept = _snapshot(aside)
    kept.pop("cli.log", None)
    assert kept == mine
    assert json.loads((run / "summary.json").read_text())["status"] == "ok"


def test_a_resumed_sweep_refuses_its_stale_jobs(tmp_path: Path, in_process) -> None:  # noqa: ANN001
    """A sweep resumed after its config changed (here: a key left out of the job names, as an
    edited config file is) is refused in one line before any job starts (exit 2, records and
    multirun.yaml intact); without the sweep's multirun.yaml, each stale job refuses in one line
    (exit 1); --force moves the old records aside and starts over."""
    sweep = tmp_path / "sweep"
    keep_names = (
        "hydra.job.config.override_dirname.exclude_keys=[hydra.sweep.dir,controller.stiffness]"
    )
    base = ["run", "-m", "experiment=smoke", "seed=0,1", *FAST, keep_names,
            f"hydra.sweep.dir={sweep}"]  # fmt: skip
    code, _, err = in_process([*base, "controller.stiffness=400"])
    assert code == 0, err
    assert in_process([*base, "controller.stiffness=400", "seed=0,1,2"])[0] == 0  # extended
    before = {k: v for k, v in _snapshot(sweep).items() if "seed=2" not in k}

    code, _, err = in_process([*base, "controller.stiffness=500"])
    assert code == cli.EXIT_CONFIG
    assert _lines(err) == [
        f"ccm: error: hydra.sweep.dir: sweep directory {sweep} holds a sweep of another config "
        "(multirun.yaml differs); run again with --force to move its records aside and start "
        "over, or choose another directory"
    ]
    assert {k: v for k, v in _snapshot(sweep).items() if "seed=2" not in k} == before

    (sweep / "multirun.yaml").rename(tmp_path / "multirun.yaml")
    code, _, err = in_process([*base, "controller.stiffness=500"])
    assert code == cli.EXIT_FAILED
    lines = _lines(err)
    assert len(lines) == 2 and all("holds a run of another config" in ln for ln in lines)
    after = _snapshot(sweep)
    assert {k: v for k, v in after.items() if "seed=2" not in k and k != "multirun.yaml"} == {
        k: v for k, v in before.items() if k != "multirun.yaml"
    }

    (tmp_path / "multirun.yaml").replace(sweep / "multirun.yaml")  # the 400 sweep's record
    code, _, err = in_process(["run", "--force", *base[1:], "controller.stiffness=500"])
    assert code == 0, err
    assert len(list(sweep.glob("multirun.yaml.replaced-*"))) == 1
    assert len(list(sweep.glob("*,seed=[01].replaced-*"))) == 2


def test_config_digest_is_deterministic(composer) -> None:  # noqa: ANN001
    a = config_digest(composer(["experiment=smoke", "seed=3"]))
    assert a == config_digest(composer(["seed=3", "experiment=smoke"]))
    assert a != config_digest(composer(["experiment=smoke", "seed=4"]))
    assert re.fullmatch(r"[0-9a-f]{64}", a)


def test_a_record_from_before_the_hash_is_checked_by_its_config(tmp_path: Path, composer) -> None:  # noqa: ANN001
    """A run directory written before config.sha256 existed: its .hydra/config.yaml decides."""
    from omegaconf import OmegaConf

    cfg = composer(["experiment=smoke"])
    (tmp_path / ".hydra").mkdir()
    (tmp_path / ".hydra" / "config.yaml").write_text(OmegaConf.to_yaml(cfg))
    with open_record(tmp_path, cfg) as record:  # the same config: resumable
        assert record.replaced is None
    with pytest.raises(RecordRefused, match="holds a run of another config"):
        with open_record(tmp_path, composer(["experiment=smoke", "seed=1"])):
            pass
    assert not (tmp_path / ".lock").exists()


def test_stale_temporary_files_are_removed(tmp_path: Path) -> None:
    (tmp_path / "timeseries" / "a").mkdir(parents=True)
    stale = [
        tmp_path / ".summary.json.k2j4_x.tmp",
        tmp_path / "timeseries/a/.trial_001.parquet.q.tmp",
    ]
    for p in stale:
        p.write_text("half")
    (tmp_path / "notes.tmp").write_text("not ours")  # not an atomic write's name
    assert sorted(clean_stale_temp(tmp_path)) == sorted(stale)
    assert not any(p.exists() for p in stale) and (tmp_path / "notes.tmp").exists()


# --- 3. interrupts ------------------------------------------------------------------------


def _trial_files(run: Path) -> list[Path]:
    return list((run / "timeseries").rglob("trial_*.parquet")) if run.is_dir() else []


@pytest.mark.parametrize("sig", [signal.SIGINT, signal.SIGTERM], ids=lambda s: s.name)
def test_a_signal_ends_a_run_with_one_line_and_an_interrupted_record(
    tmp_path: Path, sig: signal.Signals
) -> None:
    run = tmp_path / "run"
    proc = _start(["run", "experiment=smoke", "experiment.trials=500",
                   "experiment.figures=false", "experiment.timeseries=all",
                   f"hydra.run.dir={run}"], tmp_path)  # fmt: skip
    _wait_for(lambda: len(_trial_files(run)) >= 2 or proc.poll() is not None)
    proc.send_signal(sig)
    out, err = proc.communicate(timeout=120)
    assert proc.returncode == 128 + sig, err
    assert "Traceback" not in err + out
    assert _lines(err) == [f"ccm: interrupted ({sig.name}); partial record in {run}"]
    summary = json.loads((run / "summary.json").read_text())
    assert summary["status"] == "interrupted" and summary["signal"] == sig.name
    assert summary["error"].startswith(f"interrupted by {sig.name} after ")
    assert 1 <= len(summary["trials"]) <= len(_trial_files(run))  # what had finished
    assert not list(run.rglob(".lock")) and not list(run.rglob("*.tmp"))


class _SignalledInDestructor:
    """Sends this process ``sig`` from ``__del__``; Python runs the handler there, where an
    exception is "ignored" (as in pymunk's cffi ``ffi.gc`` destructor of its space)."""

    def __init__(self, sig: signal.Signals) -> None:
        self.sig = sig

    def __del__(self) -> None:
        os.kill(os.getpid(), self.sig)
        sum(range(1000))  # bytecode after the kill: the handler runs inside __del__


@pytest.mark.parametrize("sig", [signal.SIGINT, signal.SIGTERM], ids=lambda s: s.name)
def test_a_signal_a_destructor_swallows_is_raised_at_the_next_trial_boundary(
    sig: signal.Signals, capsys: pytest.CaptureFixture[str]
) -> None:
    """The cause of an intermittent SIGTERM run that ended ``ok`` with exit 0: the handler's
    RunInterrupted, raised inside a destructor, was printed as "Exception ignored" and lost."""
    from ccm.experiment.interrupts import RunInterrupted, interrupts_raise, raise_if_interrupted

    reached = []
    before = signal.getsignal(sig)  # SIG_IGN for SIGINT where the suite runs in the background
    with pytest.raises(RunInterrupted) as caught:
        with interrupts_raise():
            _SignalledInDestructor(sig)  # dropped at once: __del__ runs here
            reached.append("after the destructor")  # the exception did not propagate
            raise_if_interrupted()  # the runner's check after each trial
            reached.append("after the check")
    assert reached == ["after the destructor"] and caught.value.signum == sig
    assert "Exception ignored" not in capsys.readouterr().err  # one line, no traceback
    raise_if_interrupted()  # emptied when the block ended: nothing pending
    assert signal.getsignal(sig) == before  # the previous handler is back


def test_a_swallowed_signal_after_the_last_trial_still_ends_the_block_interrupted() -> None:
    from ccm.experiment.interrupts import RunInterrupted, interrupts_raise

    hook = sys.unraisablehook
    with pytest.raises(RunInterrupted, match="SIGTERM"):
        with interrupts_raise():
            _SignalledInDestructor(signal.SIGTERM)
    assert sys.unraisablehook is hook


def test_the_trial_loop_raises_a_swallowed_signal_after_the_trial_it_ended(
    composer, tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    """The runner's check: the run stops after the trial in which a destructor swallowed the
    signal, with that trial among the finished ones (the interrupted record keeps them)."""
    from ccm.experiment import runner
    from ccm.experiment.interrupts import RunInterrupted, interrupts_raise

    real = runner.run_trial
    calls = []

    def run_trial(*args: Any, **kwargs: Any) -> Any:
        calls.append(1)
        if len(calls) == 2:
            _SignalledInDestructor(signal.SIGTERM)
        return real(*args, **kwargs)

    monkeypatch.setattr(runner, "run_trial", run_trial)
    args = ["experiment=smoke", "experiment.max_time_s=0.05", "experiment.figures=false"]
    finished: list[dict] = []
    with pytest.raises(RunInterrupted), interrupts_raise():
        runner.run_experiment(composer(args), lambda extra: composer([*args, *extra]),
                              tmp_path, False, finished=finished)  # fmt: skip
    assert len(calls) == 2 and [t["trial"] for t in finished] == [1, 2]
    assert not (tmp_path / "summary.json").exists()


def test_other_unraisable_exceptions_still_reach_the_previous_hook() -> None:
    from ccm.experiment.interrupts import interrupts_raise

    seen: list[BaseException] = []
    hook = sys.unraisablehook
    sys.unraisablehook = lambda u: seen.append(u.exc_value)
    try:
        with interrupts_raise():

            class Broken:
                def __del__(self) -> None:
                    raise ValueError("from a destructor")

            Broken()
    finally:
        sys.unraisablehook = hook
    assert [str(e) for e in seen] == ["from a destructor"]


def _children(pid: int) -> set[int]:
    out = set()
    for stat in Path("/proc").glob("[0-9]*/stat"):
        try:
            fields = stat.read_text().rsplit(")", 1)[1].split()
        except OSError:
            continue
        if int(fields[1]) == pid:
            out.add(int(stat.parent.name))
    return out


def _alive(pid: int) -> bool:
    try:
        state = Path(f"/proc/{pid}/stat").read_text().rsplit(")", 1)[1].split()[0]
    except OSError:
        return False
    return state != "Z"


@pytest.mark.skipif(not Path("/proc/self/stat").exists(), reason="reads /proc")
@pytest.mark.parametrize("sig", [signal.SIGINT, signal.SIGTERM], ids=lambda s: s.name)
def test_a_signal_to_a_local_sweep_stops_its_workers(tmp_path: Path, sig: signal.Signals) -> None:
    """``kill`` of the launching process alone (as a scheduler or ``kill PID`` does): its loky
    workers record their jobs as interrupted and exit with it; one line, exit 128 + signal."""
    sweep = tmp_path / "sweep"
    proc = _start(["run", "-m", "experiment=smoke", "seed=0,1,2,3", "experiment.trials=500",
                   "experiment.figures=false", "experiment.timeseries=all", "hydra/launcher=local",
                   f"hydra.sweep.dir={sweep}"], tmp_path)  # fmt: skip
    # two jobs under way, each with a trial done (its record follows its time series file)
    _wait_for(lambda: sum(len(_trial_files(j)) >= 2 for j in sweep.glob("*")) >= 2)
    workers = _children(proc.pid)
    proc.send_signal(sig)
    out, err = proc.communicate(timeout=120)
    assert proc.returncode == 128 + sig, err
    assert "Traceback" not in err + out
    assert _lines(err) == [f"ccm: interrupted ({sig.name}); partial records in {sweep}"]
    time.sleep(0.5)
    assert not [p for p in workers if _alive(p) and "popen_loky" in _cmdline(p)]
    started = [j for j in sweep.glob("*") if (j / ".hydra").is_dir()]
    assert len(started) == 2  # two workers, the first two jobs
    for job in started:
        summary = json.loads((job / "summary.json").read_text())
        assert summary["status"] == "interrupted" and summary["signal"] == sig.name
        assert len(summary["trials"]) >= 1
    assert not list(sweep.rglob(".lock")) and not list(sweep.rglob("*.tmp"))


def _cmdline(pid: int) -> str:
    try:
        return Path(f"/proc/{pid}/cmdline").read_text().replace("\0", " ")
    except OSError:
        return ""


def _orphaned_worker(out: str, spawner: int) -> None:
    """A 'sweep worker' whose launcher dies before its job starts (the race of a SIGKILL)."""
    from ccm.experiment.interrupts import RunInterrupted, die_with_launcher, interrupts_raise

    deadline = time.monotonic() + 30.0
    while os.getppid() == spawner and time.monotonic() < deadline:
        time.sleep(0.01)
    result = "launcher still alive"
    try:
        with interrupts_raise():
            die_with_launcher()
            result = "not signalled"
            time.sleep(5.0)
    except RunInterrupted as exc:
        result = exc.name
    Path(out).write_text(result)


def _launcher_that_dies(out: str) -> None:
    import multiprocessing

    os.environ["CCM_LAUNCHER_PID"] = str(os.getpid())  # as ccm.experiment.interrupts.launcher_env
    multiprocessing.get_context("fork").Process(
        target=_orphaned_worker, args=(out, os.getpid())
    ).start()
    os._exit(0)


@pytest.mark.skipif(not sys.platform.startswith("linux"), reason="PR_SET_PDEATHSIG is Linux's")
def test_a_worker_whose_launcher_died_before_its_job_stops(tmp_path: Path) -> None:
    """The kernel's parent-death signal only covers a launcher that dies after the worker set
    it; a worker that starts its job after its launcher was killed stops at once as well."""
    import multiprocessing

    out = tmp_path / "result"
    launcher = multiprocessing.get_context("fork").Process(
        target=_launcher_that_dies, args=(str(out),)
    )
    launcher.start()
    launcher.join(30)
    _wait_for(out.is_file, timeout=60)
    assert out.read_text() == "SIGTERM"

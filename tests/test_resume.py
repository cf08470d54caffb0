"""Resume without data loss (issue #8 part 5): a sweep killed with SIGKILL mid-run and run
again ends with the same results as an uninterrupted sweep; finished jobs are skipped, never
redone or overwritten. With the basic launcher and with the local one (issue #19): there only
the launching process is killed, its loky workers stop with it (or their run directories'
locks keep the re-run out while they finish), and the resumed sweep leaves no lock or stale
temporary file behind."""

from __future__ import annotations

import fcntl
import json
import os
import signal
import subprocess
import sys
import time
from pathlib import Path

import pytest

SWEEP = ["run", "-m", "experiment=smoke", "seed=0,1,2,3", "experiment.figures=false"]


def _cmd(sweep_dir: Path, launcher: str = "basic") -> list[str]:
    extra = [] if launcher == "basic" else [f"hydra/launcher={launcher}"]
    return [sys.executable, "-m", "ccm.cli", *SWEEP, *extra, f"hydra.sweep.dir={sweep_dir}"]


def _env() -> dict[str, str]:
    return {k: v for k, v in os.environ.items() if k != "HYDRA_FULL_ERROR"}


def _ok(sweep_dir: Path) -> list[Path]:
    out = []
    for p in sorted(sweep_dir.glob("*/summary.json")):
        try:
            if json.loads(p.read_text(encoding="utf-8")).get("status") == "ok":
                out.append(p)
        except (OSError, json.JSONDecodeError):
            pass
    return out


def _locked(sweep_dir: Path) -> bool:
    """Whether a process still holds the lock of a job directory (an orphaned worker)."""
    for lock in sweep_dir.glob("*/.lock"):
        try:
            with open(lock) as fh:
                fcntl.flock(fh, fcntl.LOCK_EX | fcntl.LOCK_NB)
        except BlockingIOError:
            return True
        except OSError:
            pass
    return False


def _workers(pid: int) -> list[int]:
    """The loky worker processes of ``pid`` (Linux: /proc), else []."""
    out = []
    for cmdline in Path("/proc").glob("[0-9]*/cmdline"):
        try:
            stat = (cmdline.parent / "stat").read_text().rsplit(")", 1)[1].split()
            if int(stat[1]) == pid and b"popen_loky" in cmdline.read_bytes():
                out.append(int(cmdline.parent.name))
        except (OSError, IndexError, ValueError):
            pass
    return out


def _running(pid: int) -> bool:
    try:
        return Path(f"/proc/{pid}/stat").read_text().rsplit(")", 1)[1].split()[0] != "Z"
    except (OSError, IndexError):
        return False


@pytest.mark.parametrize("launcher", ["basic", "local"])
def test_sigkill_then_rerun_equals_an_uninterrupted_sweep(tmp_path: Path, launcher: str) -> None:
    full = subprocess.run(_cmd(tmp_path / "full", launcher), env=_env(), capture_output=True,
                          text=True, timeout=300, check=False)  # fmt: skip
    assert full.returncode == 0, full.stderr[-400:]

    cut = tmp_path / "cut"
    proc = subprocess.Popen(_cmd(cut, launcher), env=_env(), stdout=subprocess.DEVNULL,
                            stderr=subprocess.DEVNULL, start_new_session=True)  # fmt: skip
    t0 = time.monotonic()
    while len(_ok(cut)) < 1 and time.monotonic() - t0 < 120 and proc.poll() is None:
        time.sleep(0.02)
    workers = _workers(proc.pid)
    if launcher == "basic":
        os.killpg(proc.pid, signal.SIGKILL)  # mid-sweep: one job done, the next one running
    else:
        os.kill(proc.pid, signal.SIGKILL)  # the launcher alone: its workers are orphaned
    proc.wait()
    t0 = time.monotonic()
    while _locked(cut) and time.monotonic() - t0 < 120:  # orphans stop (or finish) first
        time.sleep(0.05)
    t0 = time.monotonic()  # Linux: they stop with their launcher (PDEATHSIG), not finish
    while [p for p in workers if _running(p)] and time.monotonic() - t0 < 30:
        time.sleep(0.05)
    assert not [p for p in workers if _running(p)]
    finished = {p: p.stat().st_mtime_ns for p in _ok(cut)}
    assert 1 <= len(finished) < 4, "the kill should land mid-sweep"
    # what a kill during an atomic write leaves (ccm.core.records.atomic_path): the resume cleans it
    unfinished = [j for j in cut.glob("*") if j.is_dir() and j / "summary.json" not in finished]
    stale = [d / ".summary.json.x1y2z3.tmp" for d in (*unfinished, *[p.parent for p in finished])]
    for path in stale:
        path.parent.mkdir(parents=True, exist_ok=True)
        path.write_text('{"status": "ok"')

    again = subprocess.run(_cmd(cut, launcher), env=_env(), capture_output=True, text=True,
                           timeout=300, check=False)  # fmt: skip
    assert again.returncode == 0, again.stderr[-400:]
    assert "skipped" in again.stdout
    for p, mtime in finished.items():  # finished jobs are not redone
        assert p.stat().st_mtime_ns == mtime
    a = {p.parent.name: p.read_bytes() for p in _ok(tmp_path / "full")}
    b = {p.parent.name: p.read_bytes() for p in _ok(cut)}
    assert len(a) == 4 and a == b
    leftovers = [p for p in cut.rglob("*") if p.name.endswith(".tmp") or p.name == ".lock"]
    assert leftovers == [], leftovers
    assert not (cut / ".refused").exists()


def test_atomic_write_leaves_no_temp_file_and_a_readable_mode(tmp_path: Path) -> None:
    from ccm.core.records import write_atomic

    target = tmp_path / "summary.json"
    write_atomic(target, "{}\n")
    write_atomic(target, '{"status": "ok"}\n')  # replaces, never appends or half-writes
    assert target.read_text() == '{"status": "ok"}\n'
    assert [p.name for p in tmp_path.iterdir()] == ["summary.json"]
    mask = os.umask(0o022)
    os.umask(mask)
    assert target.stat().st_mode & 0o777 == 0o666 & ~mask  # not mkstemp's 0600

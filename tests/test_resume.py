"""Resume without data loss (issue #8 part 5): a sweep killed with SIGKILL mid-run and run
again ends with the same results as an uninterrupted sweep; finished jobs are skipped, never
redone or overwritten."""

from __future__ import annotations

import json
import os
import signal
import subprocess
import sys
import time
from pathlib import Path

SWEEP = ["run", "-m", "experiment=smoke", "seed=0,1,2,3", "experiment.figures=false"]


def _cmd(sweep_dir: Path) -> list[str]:
    return [sys.executable, "-m", "ccm.cli", *SWEEP, f"hydra.sweep.dir={sweep_dir}"]


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


def test_sigkill_then_rerun_equals_an_uninterrupted_sweep(tmp_path: Path) -> None:
    full = subprocess.run(_cmd(tmp_path / "full"), env=_env(), capture_output=True,
                          text=True, timeout=300, check=False)  # fmt: skip
    assert full.returncode == 0, full.stderr[-400:]

    cut = tmp_path / "cut"
    proc = subprocess.Popen(_cmd(cut), env=_env(), stdout=subprocess.DEVNULL,
                            stderr=subprocess.DEVNULL, start_new_session=True)  # fmt: skip
    t0 = time.monotonic()
    while len(_ok(cut)) < 1 and time.monotonic() - t0 < 120 and proc.poll() is None:
        time.sleep(0.02)
    os.killpg(proc.pid, signal.SIGKILL)  # mid-sweep: one job done, the next one running
    proc.wait()
    finished = {p: p.stat().st_mtime_ns for p in _ok(cut)}
    assert 1 <= len(finished) < 4, "the kill should land mid-sweep"

    again = subprocess.run(_cmd(cut), env=_env(), capture_output=True, text=True,
                           timeout=300, check=False)  # fmt: skip
    assert again.returncode == 0, again.stderr[-400:]
    assert "skipped" in again.stdout
    for p, mtime in finished.items():  # finished jobs are not redone
        assert p.stat().st_mtime_ns == mtime
    a = {p.parent.name: p.read_bytes() for p in _ok(tmp_path / "full")}
    b = {p.parent.name: p.read_bytes() for p in _ok(cut)}
    assert len(a) == 4 and a == b


def test_atomic_write_leaves_no_temp_file_and_a_readable_mode(tmp_path: Path) -> None:
    from ccm.records import write_atomic

    target = tmp_path / "summary.json"
    write_atomic(target, "{}\n")
    write_atomic(target, '{"status": "ok"}\n')  # replaces, never appends or half-writes
    assert target.read_text() == '{"status": "ok"}\n'
    assert [p.name for p in tmp_path.iterdir()] == ["summary.json"]
    mask = os.umask(0o022)
    os.umask(mask)
    assert target.stat().st_mode & 0o777 == 0o666 & ~mask  # not mkstemp's 0600

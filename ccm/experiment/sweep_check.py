"""Hydra callback that finds the jobs of a sweep that did not end ``ok`` (issue #8).

A ``ccm run`` job never raises: it writes ``summary.json`` (``status: failed`` and the cause
on failure) and prints one line, so Hydra does not print a traceback per failed job. After
the sweep, :class:`SweepCheck` (configured under ``hydra.callbacks`` in configs/config.yaml)
reads every job directory's summary in the launching process, whatever launcher ran the
jobs (in-process, joblib workers, a cluster), and ``ccm run -m`` exits non-zero if any job
failed or left no summary (killed), or was refused its directory (in use by another run, or
holding another config's record: :mod:`ccm.experiment.run_record`). A refused job writes nothing
into its directory; it leaves a marker in ``<sweep dir>/.refused/`` instead, which the check reads.
"""

from __future__ import annotations

import hashlib
import shutil
from pathlib import Path
from typing import Any

from hydra.experimental.callback import Callback

from ccm.core.records import read_json_object
from ccm.experiment.run_record import REPLACED

#: Job directories of the last sweep in this process that did not end ok.
FAILED_JOBS: list[str] = []
#: ``sweep_dir`` of the sweep running in this process (for ``ccm run``'s interrupt line)
ACTIVE: dict[str, str] = {}
REFUSED_DIR = ".refused"


def mark_refused(sweep_dir: Path, job_dir: Path, message: str) -> None:
    """Record, beside the job directory it must not touch, that a job was refused."""
    from ccm.core.records import write_atomic

    name = hashlib.sha256(str(job_dir).encode()).hexdigest()[:16]
    write_atomic(Path(sweep_dir) / REFUSED_DIR / name, f"{job_dir}\t{message}\n")


def sweep_failures(sweep_dir: Path) -> list[str]:
    """Job directories (those with a ``.hydra/``) whose summary.json is missing or not ok,
    then the refused ones; moved-aside records (``--force``) are not jobs of the sweep."""
    bad = []
    for job in sorted(p.parent for p in Path(sweep_dir).glob("*/.hydra")):
        if REPLACED in job.name:
            continue
        summary = read_json_object(job / "summary.json")
        status = None if summary is None else summary.get("status")
        if status != "ok":
            bad.append(str(job))
    refused = Path(sweep_dir) / REFUSED_DIR
    for marker in sorted(refused.glob("[!.]*")) if refused.is_dir() else ():
        job_dir = marker.read_text(encoding="utf-8").partition("\t")[0]
        if job_dir not in bad:
            bad.append(job_dir)
    return bad


class SweepCheck(Callback):
    """Record the jobs of a finished sweep that did not end ok in :data:`FAILED_JOBS`."""

    def on_multirun_start(self, config: Any, **kwargs: Any) -> None:
        sweep_dir = Path(str(config.hydra.sweep.dir))
        ACTIVE["sweep_dir"] = str(sweep_dir)
        shutil.rmtree(sweep_dir / REFUSED_DIR, ignore_errors=True)  # an earlier sweep's

    def on_multirun_end(self, config: Any, **kwargs: Any) -> None:
        sweep_dir = Path(str(config.hydra.sweep.dir))
        FAILED_JOBS.extend(sweep_failures(sweep_dir))
        shutil.rmtree(sweep_dir / REFUSED_DIR, ignore_errors=True)  # read: done with

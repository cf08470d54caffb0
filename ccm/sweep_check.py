"""Hydra callback that finds the jobs of a sweep that did not end ``ok`` (issue #8).

A ``ccm run`` job never raises: it writes ``summary.json`` (``status: failed`` and the cause
on failure) and prints one line, so Hydra does not print a traceback per failed job. After
the sweep, :class:`SweepCheck` (configured under ``hydra.callbacks`` in configs/config.yaml)
reads every job directory's summary in the launching process, whatever launcher ran the
jobs (in-process, joblib workers, a cluster), and ``ccm run -m`` exits non-zero if any job
failed or left no summary (killed).
"""

from __future__ import annotations

import json
from pathlib import Path
from typing import Any

from hydra.experimental.callback import Callback

#: Job directories of the last sweep in this process that did not end ok.
FAILED_JOBS: list[str] = []


def sweep_failures(sweep_dir: Path) -> list[str]:
    """Job directories (those with a ``.hydra/``) whose summary.json is missing or not ok."""
    bad = []
    for job in sorted(p.parent for p in Path(sweep_dir).glob("*/.hydra")):
        try:
            status = json.loads((job / "summary.json").read_text(encoding="utf-8")).get("status")
        except (OSError, json.JSONDecodeError):
            status = None
        if status != "ok":
            bad.append(str(job))
    return bad


class SweepCheck(Callback):
    """Record the jobs of a finished sweep that did not end ok in :data:`FAILED_JOBS`."""

    def on_multirun_end(self, config: Any, **kwargs: Any) -> None:
        FAILED_JOBS.extend(sweep_failures(Path(config.hydra.sweep.dir)))

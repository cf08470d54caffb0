"""``load_run``: one run directory as pandas DataFrames, for analysis in a notebook or
script (issue #19; docs/user-guide/running.md, "Time series, and analysing a run")::

    from ccm.reporting.load import load_run

    run = load_run("outputs/smoke/2026-12-03_08-00-00-000000")
    run.conditions  # one row per condition (index): the summary's metrics (last phase)
    run.trials      # one row per trial: condition, phase, trial, seed, then its metrics
    run.timeseries  # long: condition, phase, trial, then one row per control step

The time series are the ``timeseries/<condition>/trial_NNN.parquet`` files the run wrote
(``experiment.timeseries`` chooses which trials: not necessarily all of them). Columns a
condition's controller does not log (e.g. another controller's signals) are NaN in the other
conditions' rows. Reads files only; runs nothing.
"""

from __future__ import annotations

import json
import re
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

from ccm.core.timeseries import read_timeseries

_TRIAL_FILE = re.compile(r"trial_(\d+)\.parquet")


@dataclass
class Run:
    """A loaded run directory (module docstring); ``summary`` is summary.json as parsed."""

    path: Path
    summary: dict[str, Any]
    conditions: Any  # pandas.DataFrame
    trials: Any  # pandas.DataFrame
    timeseries: Any = field(repr=False)  # pandas.DataFrame (empty: no files, or not loaded)


def load_run(run_dir: str | Path, timeseries: bool = True) -> Run:
    """Load ``run_dir``'s summary.json and (if ``timeseries``) its time-series files.

    Raises :class:`FileNotFoundError` when the directory holds no summary.json (not a run
    directory, or a run that has not finished), :class:`ValueError` for a summary.json that
    is not a ccm summary.
    """
    import pandas as pd

    path = Path(run_dir)
    summary_path = path / "summary.json"
    if not summary_path.is_file():
        what = "does not exist" if not path.exists() else "holds no summary.json"
        raise FileNotFoundError(
            f"{path} {what}: not a ccm run directory, or its run has not finished"
        )
    summary = json.loads(summary_path.read_text(encoding="utf-8"))
    if not isinstance(summary, dict) or not isinstance(summary.get("conditions", {}), dict):
        raise ValueError(f"{summary_path}: not a ccm summary (a JSON object with 'conditions')")
    conditions = pd.DataFrame.from_dict(summary.get("conditions") or {}, orient="index")
    conditions.index.name = "condition"
    trials = pd.DataFrame(summary.get("trials") or [])
    series = _load_timeseries(path, trials) if timeseries else pd.DataFrame()
    return Run(path, summary, conditions, trials, series)


def _load_timeseries(run_dir: Path, trials: Any) -> Any:
    """Every ``timeseries/<condition>/trial_NNN.parquet`` as one long DataFrame."""
    import pandas as pd

    phase: dict[tuple[str, int], str] = {}
    if {"condition", "trial", "phase"} <= set(trials.columns):
        for c, t, p in trials[["condition", "trial", "phase"]].itertuples(index=False):
            phase[(str(c), int(t))] = str(p)
    frames = []
    for file in sorted((run_dir / "timeseries").glob("*/trial_*.parquet")):
        match = _TRIAL_FILE.fullmatch(file.name)
        if match is None:
            continue
        cond, trial = file.parent.name, int(match.group(1))
        frame = pd.DataFrame(read_timeseries(file))
        frame.insert(0, "trial", trial)
        frame.insert(0, "phase", phase.get((cond, trial)))
        frame.insert(0, "condition", cond)
        frames.append(frame)
    if not frames:
        return pd.DataFrame(columns=["condition", "phase", "trial"])
    return pd.concat(frames, ignore_index=True)

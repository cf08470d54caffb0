"""An entry's results, the stored entries, and the leaderboard that ranks them.

**Results** (``results.json`` of a suite run; ``ccm/suite/results/<suite>/<entry>.json`` for
the built-in entries): the suite, its version, the entry's controller overrides, each task's
fingerprint, and per task its status and per seed the scored trials' mean of every suite
metric. A task with a failed seed is ``failed`` (the first failure's cause is kept).

**Ranks.** In each cell (a task and one metric it ranks), the entries are ranked by their
mean over seeds as the board shows it (4 significant figures: equal numbers on the board are
a tie, and a difference far below the seeds' spread does not order two entries), lower is
better, ties sharing the mean rank; an entry that failed the task
takes the last rank (the number of entries) in each of its cells; one without a value there
(no contact, so no overshoot) is not ranked in that cell. An entry's score is its mean rank
over the cells it is ranked in; the board is sorted by it. Every mean comes with its 95 %
Student-t interval over seeds (:func:`ccm.core.stats.mean_ci`).
"""

from __future__ import annotations

import json
import math
from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from ccm.core.errors import ConfigError
from ccm.core.stats import mean_ci
from ccm.suite.definition import Suite, results_dir


def entry_results(
    suite: Suite,
    entry: str,
    overrides: Sequence[str],
    rows: Sequence[Mapping[str, Any]],
    prints: Mapping[str, str],
) -> dict[str, Any]:
    """An entry's results from its job rows (:func:`ccm.suite.runner.run_job`)."""
    tasks: dict[str, Any] = {}
    for name in prints:
        mine = [r for r in rows if r["task"] == name]
        bad = [r for r in mine if r["status"] != "ok"]
        tasks[name] = {
            "status": "failed" if bad else "ok",
            "error": f"seed {bad[0]['seed']}: {bad[0]['error']}" if bad else None,
            "seeds": {str(r["seed"]): r["metrics"] for r in mine if r["status"] == "ok"},
        }
    return {
        "suite": suite.name,
        "version": suite.version,
        "entry": entry,
        "controller": list(overrides),
        "fingerprints": dict(prints),
        "tasks": tasks,
    }


def load_stored(suite: Suite) -> dict[str, dict[str, Any]]:
    """The built-in entries' stored results (entry name -> results), in name order."""
    out = {}
    for path in sorted(results_dir(suite).glob("*.json")):  # leaderboard.md is not one
        data = json.loads(path.read_text())
        if data.get("suite") != suite.name or data.get("version") != suite.version:
            got = f"{data.get('suite')} v{data.get('version')}"
            raise ConfigError(
                str(path), f"holds results of {got}, not {suite.name} v{suite.version}"
            )
        out[str(data["entry"])] = data
    return out


def stale_tasks(results: Mapping[str, Any], prints: Mapping[str, str]) -> list[str]:
    """The tasks whose stored fingerprint differs from today's (another scene or protocol)."""
    have = results.get("fingerprints") or {}
    return [t for t, fp in prints.items() if t in have and have[t] != fp]


@dataclass
class Cell:
    """One entry on one task and metric: mean and 95 % half-width over seeds, its rank."""

    mean: float | None
    half: float | None
    n: int
    rank: float | None = None


@dataclass
class Board:
    """The ranked leaderboard (module docstring)."""

    suite: Suite
    entries: list[str]  # sorted by score
    score: dict[str, float | None]
    cells: dict[tuple[str, str, str], Cell]  # (entry, task, metric)
    status: dict[tuple[str, str], str]  # (entry, task) -> ok | failed | missing
    errors: dict[tuple[str, str], str] = field(default_factory=dict)
    tasks: list[str] = field(default_factory=list)


def _cell(seeds: Mapping[str, Mapping[str, Any]], metric: str) -> Cell:
    vals = [float(m[metric]) for m in seeds.values() if isinstance(m.get(metric), int | float)]
    if not vals:
        return Cell(None, None, 0)
    mean, half = mean_ci(vals)
    return Cell(mean, None if math.isnan(half) else half, len(vals))


def shown(x: float | None) -> float:
    """``x`` to the 4 significant figures the board prints (what is ranked)."""
    return float(f"{x:.4g}")


def rank_entries(suite: Suite, results: Mapping[str, Mapping[str, Any]],
                 tasks: Sequence[str]) -> Board:  # fmt: skip
    """Rank ``results`` (entry -> results) on ``tasks`` (module docstring)."""
    from scipy.stats import rankdata

    names = list(results)
    cells: dict[tuple[str, str, str], Cell] = {}
    status: dict[tuple[str, str], str] = {}
    errors: dict[tuple[str, str], str] = {}
    ranks: dict[str, list[float]] = {e: [] for e in names}
    for t in tasks:
        for e in names:
            got = results[e]["tasks"].get(t)
            status[(e, t)] = "missing" if got is None else got["status"]
            if got is not None and got.get("error"):
                errors[(e, t)] = str(got["error"])
        for m in suite.metrics:
            for e in names:
                seeds = (results[e]["tasks"].get(t) or {}).get("seeds") or {}
                cells[(e, t, m)] = _cell(seeds, m)
        for m in suite.tasks[t].ranked:
            ok = [e for e in names if status[(e, t)] == "ok" and cells[(e, t, m)].mean is not None]
            r = rankdata([shown(cells[(e, t, m)].mean) for e in ok]) if ok else []
            for e, rank in zip(ok, r, strict=True):
                cells[(e, t, m)].rank = float(rank)
            for e in names:
                if status[(e, t)] == "failed":
                    cells[(e, t, m)].rank = float(len(names))
                if cells[(e, t, m)].rank is not None:
                    ranks[e].append(cells[(e, t, m)].rank)
    score = {e: float(np.mean(r)) if r else None for e, r in ranks.items()}
    order = sorted(names, key=lambda e: (score[e] is None, score[e] or 0.0, e))
    return Board(suite, order, score, cells, status, errors, list(tasks))

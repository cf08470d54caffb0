"""Which runs a report may pool, and which it must set aside (issue #19).

:func:`ccm.reporting.report_runs.collect` reads every run under a directory. Pooling all of
them can mislead:

* **duplicates** — the same experiment, seed and task run twice (a sweep re-run into another
  directory, a copied run) would count as two seeds. The first run by path is kept, preferring
  one whose status is ``ok``; every other is set aside as a duplicate of it;
* **replaced records** — ``ccm run --force`` moves an old record aside to
  ``<dir>.replaced-<timestamp>`` (:mod:`ccm.experiment.run_record`); it is history, not a run to
  pool;
* **mixed modes** — truncated runs (``experiment.fast`` or ``max_time_s``, e.g. ``make
  reproduce-paper-quick``) beside full ones would pool smoke-test numbers with results. When
  both kinds are present, the truncated ones are set aside; a report of truncated runs only
  keeps them, under its "not results" banner.

Failed and interrupted runs are not set aside: the claims count them as missing seeds
(:func:`ccm.reporting.claims.evaluate`), and the report lists them with their causes.
"""

from __future__ import annotations

from collections.abc import Callable, Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from ccm.experiment.run_record import REPLACED

Run = tuple[Path, dict[str, Any]]


@dataclass(frozen=True)
class SetAside:
    """A run the report does not pool, and why (one line)."""

    run: Path
    kind: str  # replaced | duplicate | mixed-mode
    reason: str


def _key(summary: dict[str, Any]) -> tuple[str, str, str]:
    """What makes two runs the same seed of the same experiment."""
    return tuple(str(summary.get(k)) for k in ("experiment", "seed", "task"))  # type: ignore[return-value]


def screen(
    runs: Sequence[Run], truncated: Callable[[Path], bool]
) -> tuple[list[Run], list[SetAside]]:
    """(runs to pool, runs set aside) of ``runs`` (module docstring); ``truncated(run_dir)``
    says whether a run's trials were cut short. Order is kept."""
    aside = [SetAside(d, "replaced", "a record moved aside by ccm run --force")
             for d, _ in runs if any(REPLACED in part for part in d.parts)]  # fmt: skip
    runs = [(d, s) for d, s in runs if not any(REPLACED in part for part in d.parts)]
    cut = {d for d, _ in runs if truncated(d)}
    if cut and len(cut) < len(runs):
        aside += [SetAside(d, "mixed-mode", "a truncated run beside full runs")
                  for d, _ in runs if d in cut]  # fmt: skip
    kept = [(d, s) for d, s in runs if not (cut and len(cut) < len(runs) and d in cut)]
    first: dict[tuple[str, str, str], Path] = {}
    for d, s in sorted(kept, key=lambda r: (r[1].get("status") != "ok", str(r[0]))):
        if s.get("experiment") is None or s.get("seed") is None:
            continue  # cannot tell which seed it is: never called a duplicate
        first.setdefault(_key(s), d)
    pooled: list[Run] = []
    for d, s in kept:
        keep = first.get(_key(s), d)
        if keep == d or s.get("experiment") is None or s.get("seed") is None:
            pooled.append((d, s))
        else:
            aside.append(SetAside(d, "duplicate", f"the same experiment, seed and task as {keep}"))
    return pooled, aside


def tally(runs: Sequence[Run], aside: Sequence[SetAside]) -> str:
    """One line: how many runs were found, pooled, failed, interrupted and set aside."""
    status: dict[str, int] = {}
    for _, s in runs:
        st = str(s.get("status", "?"))
        status[st] = status.get(st, 0) + 1
    kinds: dict[str, int] = {}
    for a in aside:
        kinds[a.kind] = kinds.get(a.kind, 0) + 1
    parts = [f"{n} {k}" for k, n in sorted(status.items()) if k != "ok"]
    parts += [f"{n} set aside ({k})" for k, n in sorted(kinds.items())]
    extra = f" ({', '.join(parts)})" if parts else ""
    return f"{len(runs) + len(aside)} runs, {status.get('ok', 0)} usable{extra}"

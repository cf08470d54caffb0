"""``ccm plots RUN_DIR...``: draw a finished run's figures again from its files (issue #40).

A trial-loop run writes, besides its numbers, ``plot_inputs.json``
(:func:`ccm.plots.run.figure_inputs`: the task's dimension and contacts, the chance bounds,
the f^r targets, the low-pass and the ``metrics`` config) and the time series of each
condition's first and last trial (``experiment.timeseries: first_last``, the default). That
is all the figures read, so they can be drawn after the run, in other processes: the run
itself draws them after ``summary.json`` is written, and ``ccm paper`` draws only those of
the runs its report shows (:func:`ccm.reporting.paper.main`). A directory that holds no
``summary.json`` is taken as a sweep: its run directories are drawn, ``--jobs`` at a time.

The figures drawn from the files equal the run's own up to the files' precision
(``experiment.timeseries_bits``: a relative error of 2e-6 at the default 18 bits).
"""

from __future__ import annotations

import argparse
import sys
from collections.abc import Sequence
from concurrent.futures import ProcessPoolExecutor
from pathlib import Path
from typing import Any

import numpy as np

from ccm.core.records import read_json_object
from ccm.core.timeseries import read_timeseries, trial_path
from ccm.plots.run import write_figures

#: the file of :func:`ccm.plots.run.figure_inputs`' data in a run directory
PLOT_INPUTS = "plot_inputs.json"


class NoFigures(Exception):
    """A directory whose figures cannot be drawn: one line saying why."""


def read_plot_inputs(run_dir: Path) -> dict[str, Any]:
    """The run's ``plot_inputs.json``; :class:`NoFigures` if it has none."""
    inputs = read_json_object(Path(run_dir) / PLOT_INPUTS)
    if inputs is None:
        raise NoFigures(
            f"{run_dir}: no {PLOT_INPUTS} (an analysis run draws its own figures; a run "
            "recorded before ccm plots existed has none)"
        )
    return inputs


def figure_logs(run_dir: Path, summary: dict[str, Any]) -> dict[str, list[dict[str, np.ndarray]]]:
    """Condition -> the columns of its first and last trial (one if it ran one), float64, in
    the summary's condition order: the logs the run drew its figures from."""
    trials: dict[str, list[int]] = {}
    for tr in summary.get("trials") or []:
        trials.setdefault(str(tr["condition"]), []).append(int(tr["trial"]))
    logs = {}
    for cond in summary.get("conditions") or {}:
        nums = sorted(set(trials.get(cond, [])))
        if not nums:
            continue
        logs[cond] = [_read(run_dir, cond, k) for k in dict.fromkeys((nums[0], nums[-1]))]
    return logs


def _read(run_dir: Path, cond: str, trial: int) -> dict[str, np.ndarray]:
    path = trial_path(run_dir, cond, trial)
    if not path.is_file():
        raise NoFigures(
            f"{run_dir}: no time series of {cond} trial {trial} ({path.name}); the figures "
            "need the first and last trial of each condition (experiment.timeseries: "
            "first_last or all)"
        )
    return {k: np.asarray(v, dtype=np.float64) for k, v in read_timeseries(path).items()}


def redraw(run_dir: Path) -> list[Path]:
    """Draw the figures of the finished run in ``run_dir`` into ``run_dir/figures``; return
    their paths. :class:`NoFigures` for a directory that cannot have them."""
    run_dir = Path(run_dir)
    summary = read_json_object(run_dir / "summary.json")
    if summary is None:
        raise NoFigures(f"{run_dir}: not a run directory (no readable summary.json)")
    if summary.get("status") != "ok":
        raise NoFigures(f"{run_dir}: status {summary.get('status')!r}; only an ok run has figures")
    inputs = read_plot_inputs(run_dir)
    return write_figures(
        run_dir / "figures", inputs, figure_logs(run_dir, summary), summary.get("trials") or []
    )


def run_dirs(path: Path) -> list[Path]:
    """``path`` if it holds a run, else the run directories of the sweep under it (those
    with a ``plot_inputs.json``), sorted; moved-aside records are left out."""
    if (path / "summary.json").is_file():
        return [path]
    found = (p.parent for p in path.rglob(PLOT_INPUTS))
    return sorted(p for p in found if ".replaced-" not in str(p.relative_to(path)))


def _draw_one(run_dir: Path) -> tuple[Path, int, str | None]:
    """(run, figures written, error line or None): a pool worker's job."""
    try:
        return run_dir, len(redraw(run_dir)), None
    except NoFigures as exc:
        return run_dir, 0, str(exc)
    except Exception as exc:  # a figure bug: the other runs are still drawn
        return run_dir, 0, f"{run_dir}: {type(exc).__name__}: {exc}"


def draw_many(dirs: Sequence[Path], jobs: int) -> list[tuple[Path, int, str | None]]:
    """:func:`redraw` each of ``dirs``, ``jobs`` processes at a time (1: in this process)."""
    if jobs <= 1 or len(dirs) <= 1:
        return [_draw_one(d) for d in dirs]
    with ProcessPoolExecutor(max_workers=min(jobs, len(dirs))) as pool:
        return list(pool.map(_draw_one, dirs))


def main(argv: Sequence[str] | None = None) -> int:
    """Draw the figures; exit 2 on a bad argument, 1 if a run's figures failed."""
    p = argparse.ArgumentParser(
        prog="ccm plots", description="Draw a finished run's figures again from its files."
    )
    p.add_argument("dirs", nargs="+", type=Path, help="run directories or sweep directories")
    p.add_argument("--jobs", type=int, default=2, help="runs drawn at once (default 2)")
    args = p.parse_args(argv)
    if args.jobs < 1:
        print(f"ccm plots: --jobs must be >= 1, got {args.jobs}", file=sys.stderr)
        return 2
    dirs: list[Path] = []
    for d in args.dirs:
        if not d.is_dir():
            print(f"ccm plots: {d}: not a directory", file=sys.stderr)
            return 2
        found = run_dirs(d)
        if not found:
            print(f"ccm plots: {d}: no run directory with {PLOT_INPUTS} under it", file=sys.stderr)
            return 2
        dirs += found
    failed = 0
    for run, n, error in draw_many(dirs, args.jobs):
        if error is None:
            print(f"ccm plots: {n} figures -> {run / 'figures'}")
        else:
            failed += 1
            print(f"ccm plots: error: {error}", file=sys.stderr)
    return 1 if failed else 0

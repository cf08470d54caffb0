"""The leaderboard as Markdown, HTML and CSV, and a figure per metric.

The Markdown and HTML hold the same tables: the overall ranking (score = mean rank, and the
mean rank per metric), then one table per task with every entry's mean ± 95 % half-width
over seeds of each metric the task ranks (its rank in brackets). The CSV is long: a row per
entry, task and metric (ranked or not), for a reader's own analysis.
"""

from __future__ import annotations

import csv
import html
import io
from collections.abc import Sequence
from pathlib import Path

import numpy as np

from ccm.core.records import save_figure, write_atomic
from ccm.suite.board import Board, Cell

RANK_NOTE = (
    "Lower is better for every metric. Per task and metric the entries are ranked by their mean "
    "over seeds as shown, to 4 significant figures (equal numbers tie and share the mean rank); "
    "an entry that failed a task takes the last rank in each of its cells; the score is the "
    "mean rank over all ranked cells, every metric weighing the same. ± is the 95 % Student-t "
    "half-width over seeds."
)


def _fmt(x: float | None) -> str:
    return "—" if x is None else f"{x:.4g}"


def cell_text(cell: Cell) -> str:
    """``mean ± half (rank)``; ``—`` without a value."""
    if cell.mean is None:
        return "—"
    half = (
        ""
        if cell.half is None
        else (" ± 0" if cell.half <= 1e-9 * abs(cell.mean) else f" ± {cell.half:.2g}")
    )
    rank = f" ({cell.rank:g})" if cell.rank is not None else ""
    return f"{cell.mean:.4g}{half}{rank}"


def tables(board: Board, mine: str | None) -> list[tuple[str, str, list[str], list[list[str]]]]:
    """(title, note, header, rows) of each table: the overall one, then one per task."""
    s = board.suite
    metrics = [m for m in s.metrics if any(m in s.tasks[t].ranked for t in board.tasks)]
    head = ["rank", "controller", "score (mean rank)", "tasks ok",
            *[f"{s.metrics[m].get('short', m)} (mean rank)" for m in metrics]]  # fmt: skip
    rows = []
    for i, e in enumerate(board.entries, 1):
        ok = sum(board.status[(e, t)] == "ok" for t in board.tasks)
        per = []
        for m in metrics:
            r = [board.cells[(e, t, m)].rank for t in board.tasks if m in s.tasks[t].ranked]
            r = [x for x in r if x is not None]
            per.append(f"{np.mean(r):.2f}" if r else "—")
        score = board.score[e]
        rows.append([str(i), e, "—" if score is None else f"{score:.2f}",
                     f"{ok}/{len(board.tasks)}", *per])  # fmt: skip
    out = [(f"{s.name} (version {s.version}): leaderboard", RANK_NOTE, head, rows)]
    for t in board.tasks:
        task = s.tasks[t]
        head = ["controller", *[f"{s.metrics[m]['label']} [{s.metrics[m]['unit']}]"
                                for m in task.ranked], "status"]  # fmt: skip
        rows = []
        for e in board.entries:
            st = board.status[(e, t)]
            note = st if st != "failed" else f"failed: {board.errors.get((e, t), '')}"
            values = [cell_text(board.cells[(e, t, m)]) for m in task.ranked]
            rows.append([e, *values, note])
        out.append((f"{t}: {task.description}", f"sim={task.sim}, task={task.task}", head, rows))
    return out


def markdown(board: Board, mine: str | None) -> str:
    s = board.suite
    lines = [f"# ccm suite {s.name}", "", s.description, "",
             f"Seeds {', '.join(map(str, s.seeds))}; per seed {s.warmup_trials} warm-up then "
             f"{s.scored_trials} scored trials.", ""]  # fmt: skip
    for title, note, head, rows in tables(board, mine):
        lines += [f"## {title}", "", note, "", "| " + " | ".join(head) + " |",
                  "|" + "---|" * len(head)]  # fmt: skip
        lines += ["| " + " | ".join(c.replace("|", "/") for c in r) + " |" for r in rows]
        lines.append("")
    return "\n".join(lines)


def html_page(board: Board, mine: str | None) -> str:
    s = board.suite
    parts = [
        "<!doctype html><html><head><meta charset='utf-8'>",
        f"<title>ccm suite {html.escape(s.name)}</title><style>body{{font-family:sans-serif;"
        "margin:2em}table{border-collapse:collapse;margin-bottom:2em}td,th{border:1px solid "
        "#bbb;padding:4px 8px;text-align:right}td:first-child,th:first-child{text-align:left}"
        "tr.mine{background:#fff3c4}</style></head><body>",
        f"<h1>ccm suite {html.escape(s.name)}</h1><p>{html.escape(s.description)}</p>",
    ]
    for title, note, head, rows in tables(board, mine):
        parts.append(f"<h2>{html.escape(title)}</h2><p>{html.escape(note)}</p><table><tr>")
        parts.append("".join(f"<th>{html.escape(h)}</th>" for h in head) + "</tr>")
        for r in rows:
            cls = " class='mine'" if mine is not None and mine in r else ""
            parts.append(f"<tr{cls}>" + "".join(f"<td>{html.escape(c)}</td>" for c in r) + "</tr>")
        parts.append("</table>")
    parts.append("</body></html>")
    return "\n".join(parts)


def csv_text(board: Board) -> str:
    buf = io.StringIO()
    w = csv.writer(buf, lineterminator="\n")
    w.writerow(["entry", "task", "metric", "unit", "ranked", "mean", "ci95_half", "n_seeds",
                "rank", "status"])  # fmt: skip
    for e in board.entries:
        for t in board.tasks:
            for m, spec in board.suite.metrics.items():
                c = board.cells[(e, t, m)]
                w.writerow([e, t, m, spec["unit"], int(m in board.suite.tasks[t].ranked),
                            _num(c.mean), _num(c.half), c.n, _num(c.rank),
                            board.status[(e, t)]])  # fmt: skip
    return buf.getvalue()


def _num(x: float | None) -> str:
    return "" if x is None else repr(float(x))


def write_board(board: Board, out_dir: Path, mine: str | None) -> list[Path]:
    """``leaderboard.md``, ``.html``, ``.csv`` and ``figures/<metric>.png`` in ``out_dir``."""
    paths = [out_dir / f"leaderboard.{ext}" for ext in ("md", "html", "csv")]
    write_atomic(paths[0], markdown(board, mine))
    write_atomic(paths[1], html_page(board, mine))
    write_atomic(paths[2], csv_text(board))
    for m in board.suite.metrics:
        tasks = [t for t in board.tasks if m in board.suite.tasks[t].ranked]
        if tasks:
            paths.append(metric_figure(board, m, tasks, out_dir / "figures" / f"{m}.png", mine))
    return paths


def metric_figure(board: Board, metric: str, tasks: Sequence[str], path: Path,
                  mine: str | None) -> Path:  # fmt: skip
    """One panel per task: each entry's mean with its 95 % interval as a horizontal bar,
    best at the top; the user's entry in orange, failed or missing ones named at the axis."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    spec = board.suite.metrics[metric]
    cols = min(4, len(tasks))
    nrows = -(-len(tasks) // cols)
    n = len(board.entries)
    fig, axes = plt.subplots(nrows, cols, figsize=(3.6 * cols, 0.32 * n * nrows + 1.4 * nrows),
                             squeeze=False)  # fmt: skip
    for ax, t in zip(axes.flat, tasks, strict=False):
        cells = [(e, board.cells[(e, t, metric)]) for e in board.entries]
        shown = {e: c.mean is not None and board.status[(e, t)] == "ok" for e, c in cells}
        cells.sort(key=lambda ec: (shown[ec[0]], -(ec[1].mean or 0.0)))  # best at the top
        y = np.arange(len(cells))
        for yi, (e, c) in zip(y, cells, strict=True):
            color = "tab:orange" if e == mine else "tab:blue"
            if shown[e]:
                ax.barh(yi, c.mean, xerr=c.half or 0.0, color=color, alpha=0.8, capsize=2)
        labels = [e if board.status[(e, t)] == "ok" else f"{e} ({board.status[(e, t)]})"
                  for e, _ in cells]  # fmt: skip
        ax.set_yticks(y, labels, fontsize=7)
        ax.set_title(t, fontsize=9)
        ax.set_xlabel(f"{spec['label']} [{spec['unit']}]", fontsize=7)
        ax.tick_params(axis="x", labelsize=7)
    for ax in list(axes.flat)[len(tasks) :]:
        ax.set_visible(False)
    yours = f"; orange: {mine}" if mine else ""
    fig.suptitle(f"{board.suite.name}: {spec['label']} (mean, 95 % CI over seeds; lower is "
                 f"better{yours})", fontsize=10)  # fmt: skip
    path.parent.mkdir(parents=True, exist_ok=True)
    save_figure(fig, path)
    return path

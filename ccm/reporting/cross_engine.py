"""``ccm compare-engines A B``: the 3-D claims' verdicts on two engines side by side (issue #42).

``A`` and ``B`` are two ``ccm paper`` output directories of the same 3-D experiments, run on
different engines (``ccm paper`` with its default ``pybullet3d``, and ``ccm paper --sim
mujoco3d``). Each claim of ``experiments/claims.yaml`` whose experiment runs on a 3-D engine
is judged on each directory's runs exactly as ``ccm report`` judges it (the same screening
of runs, :func:`ccm.reporting.report_runs.usable_runs`, and :func:`ccm.reporting.claims.evaluate`);
the table has one column per engine and marks the claims whose verdict differs. Written to
``B/cross_engine.md`` and printed.
"""

from __future__ import annotations

from collections.abc import Sequence
from pathlib import Path

from ccm.core.errors import ConfigError
from ccm.reporting.claims import Verdict, evaluate, load_claims
from ccm.reporting.paper import THREE_D_ENGINES, experiment_sim
from ccm.reporting.report import DEFAULT_CLAIMS
from ccm.reporting.report_runs import usable_runs


def engine_of(root: Path) -> str:
    """The 3-D engine the runs under ``root`` used (``sim.name`` of their Hydra configs), or
    ``?`` if none or several."""
    from omegaconf import OmegaConf

    names = set()
    for run, _ in usable_runs(root)[0]:
        cfg = run / ".hydra" / "config.yaml"
        if cfg.is_file():
            names.add(OmegaConf.select(OmegaConf.load(cfg), "sim.name"))
    names &= set(THREE_D_ENGINES)
    return names.pop() if len(names) == 1 else "?"


def verdicts(root: Path, claims_path: Path, experiments: set[str]) -> dict[str, Verdict]:
    """The verdict of every claim of ``experiments`` on the runs under ``root``."""
    summaries = [s for _, s in usable_runs(root)[0]]
    return {c.id: evaluate(c, summaries) for c in load_claims(claims_path)
            if c.experiment in experiments}  # fmt: skip


def table(a: Path, b: Path, claims_path: Path = DEFAULT_CLAIMS) -> str:
    """The side-by-side table of the module docstring, in Markdown."""
    claims = load_claims(claims_path)
    experiments = {c.experiment for c in claims}
    three_d = {e for e in experiments if experiment_sim(e) in THREE_D_ENGINES}
    va, vb = verdicts(a, claims_path, three_d), verdicts(b, claims_path, three_d)
    ea, eb = engine_of(a), engine_of(b)
    rows = [f"| claim | experiment | {ea} | {eb} | differs |", "|---|---|---|---|---|"]
    differ = 0
    for c in claims:
        if c.id not in va:
            continue
        x, y = va[c.id], vb[c.id]
        measured = "not measured" not in (x.verdict, y.verdict)
        mark = "**yes**" if measured and x.verdict != y.verdict else ""
        differ += bool(mark)
        rows.append(f"| {c.id} | {c.experiment} | {x.verdict}: {x.ours} | "
                    f"{y.verdict}: {y.ours} | {mark} |")  # fmt: skip
    head = (f"{len(va)} claims of the 3-D experiments; {differ} with a different verdict "
            f"on {ea} ({a}) and {eb} ({b}).\n\n")  # fmt: skip
    return head + "\n".join(rows) + "\n"


def main(argv: Sequence[str]) -> int:
    """``ccm compare-engines A B``: write ``B/cross_engine.md`` and print it."""
    if len(argv) != 2:
        raise ConfigError("compare-engines", "usage: ccm compare-engines PAPER_DIR_A PAPER_DIR_B")
    a, b = (Path(x) for x in argv)
    for d in (a, b):
        if not d.is_dir():
            raise ConfigError("compare-engines", f"{d} is not a directory")
    text = table(a, b)
    (b / "cross_engine.md").write_text(text, encoding="utf-8")
    print(text, end="")
    return 0

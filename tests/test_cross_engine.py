"""``ccm compare-engines`` (issue #42): the 3-D claims judged on two paper runs, one column per
engine, the claims whose verdict differs marked. Two synthetic paper directories of
``h4_collisions`` (5 seeds each): on one engine contact handling cuts the impact peak to a
tenth (seed A's claim: at most 0.16), on the other to a half."""

from __future__ import annotations

import json
from pathlib import Path

from ccm.cli import main as cli
from ccm.reporting.cross_engine import table


def _paper(root: Path, engine: str, full_peak: float) -> Path:
    for seed in range(5):
        run = root / f"seed={seed}"
        (run / ".hydra").mkdir(parents=True)
        (run / ".hydra" / "config.yaml").write_text(f"sim:\n  name: {engine}\n")
        conditions = {"full": {"peak_impact_force_N": full_peak + 0.1 * seed},
                      "no_contact_handling": {"peak_impact_force_N": 60.0 + seed}}  # fmt: skip
        summary = {"experiment": "h4_collisions", "status": "ok", "seed": seed,
                   "task": "h4_collisions", "conditions": conditions, "trials": []}  # fmt: skip
        (run / "summary.json").write_text(json.dumps(summary))
    return root


def test_the_engines_verdicts_side_by_side(tmp_path: Path) -> None:
    a = _paper(tmp_path / "pb", "pybullet3d", 6.0)
    b = _paper(tmp_path / "mj", "mujoco3d", 30.0)
    text = table(a, b)
    assert "| claim | experiment | pybullet3d | mujoco3d | differs |" in text
    row = next(r for r in text.splitlines() if r.startswith("| H4-impact-force |"))
    cells = [c.strip() for c in row.split("|")]
    assert cells[3].startswith("reproduced") and cells[4].startswith("not reproduced")
    assert cells[5] == "**yes**"
    assert "h1_adaptive_control" not in text  # a 2-D experiment has no second engine
    # and H4-impact-force-full-absolute (at most 8 N): the two measured claims differ
    assert " 2 with a different verdict" in text.splitlines()[0]
    assert cli(["compare-engines", str(a), str(b)]) == 0
    assert (b / "cross_engine.md").read_text() == text
    assert cli(["compare-engines", str(a)]) == 2

"""Same results from the fast closed loop (issue #20): summary metrics of fast-mode runs
(smoke; AVIC on porridge stirring; AVIC + modes on the 2D changing surface; PyBullet table_wall
and h4_collisions with contact) equal the pins in
``tests/data/loop_reference.json``, recorded before the loop was sped up.

Speed work (compiled kernels, buffers, fewer allocations) must not change a result beyond
floating-point reassociation: relative 1e-9 (absolute 1e-12 near zero).
"""

from __future__ import annotations

import json
import math
from pathlib import Path
from typing import Any

import pytest

from tests.loop_reference import RUNS, run_metrics

PINS = json.loads((Path(__file__).parent / "data" / "loop_reference.json").read_text("utf-8"))


def _differences(ref: Any, got: Any, path: str = "") -> list[str]:
    """Every place where ``got`` departs from ``ref`` (nested dicts of numbers / None)."""
    if isinstance(ref, dict):
        if not isinstance(got, dict) or set(ref) != set(got):
            return [
                f"{path}: keys {sorted(ref)} != {sorted(got) if isinstance(got, dict) else got}"
            ]
        return [d for k in ref for d in _differences(ref[k], got[k], f"{path}/{k}")]
    if isinstance(ref, float) and isinstance(got, int | float):
        if math.isclose(ref, got, rel_tol=1e-9, abs_tol=1e-12):
            return []
        return [f"{path}: {got!r} != pinned {ref!r}"]
    return [] if ref == got else [f"{path}: {got!r} != pinned {ref!r}"]


def test_differences_reports_a_changed_metric() -> None:
    """The comparison itself can fail: a relative change of 1e-6 is reported."""
    assert _differences({"a": {"m": 1.0}}, {"a": {"m": 1.0 + 1e-6}}) == [
        "/a/m: 1.000001 != pinned 1.0"
    ]
    assert _differences({"a": 1.0}, {"a": 1.0 + 1e-12}) == []


@pytest.mark.parametrize("name", list(RUNS))
def test_fast_run_metrics_match_the_pins(composer, name: str) -> None:
    diffs = _differences(PINS[name], json.loads(json.dumps(run_metrics(composer, name))))
    assert not diffs, "\n".join(diffs)

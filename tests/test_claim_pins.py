"""Pins on the verdict rules of ``ccm.claims`` (issue #18, item 7, "Nothing else pins these").

A bound or ratio that is read loosely turns a failing claim into a reproduced one. These tests
put the compared quantity just inside and just outside each rule's ``value`` and check that
the verdict follows it, over five seeds that all agree (so the verdict is the rule's alone,
not the seeds' spread).
"""

from __future__ import annotations

from collections.abc import Sequence
from typing import Any

import pytest

from ccm.claims import evaluate, parse_claim

SEEDS = 5  # the papers' experiments sweep seeds 0-4

BASE: dict[str, Any] = {
    "id": "pin", "paper": "seed_a", "source": "§4.5.1, H4; Fig. 16",
    "statement": "impact force with contact handling against the baseline",
    "paper_value": "<= 8 N vs > 50 N", "experiment": "e",
    "a": {"condition": "full", "metric": "peak_impact_force_N"},
    "b": {"condition": "baseline", "metric": "peak_impact_force_N"},
}  # fmt: skip


def verdict(claim: dict[str, Any], full: float, baseline: float = 50.0) -> str:
    """The verdict of ``claim`` over :data:`SEEDS` ok runs that all measured ``full`` and
    ``baseline`` as the two conditions' ``peak_impact_force_N``."""
    c = parse_claim({**BASE, **claim}, "claims[0]")
    values = {"full": {"peak_impact_force_N": full}, "baseline": {"peak_impact_force_N": baseline}}
    run = {"experiment": "e", "status": "ok", "conditions": values, "trials": []}
    runs: Sequence[dict[str, Any]] = [{**run, "seed": seed} for seed in range(SEEDS)]
    return evaluate(c, runs).verdict


@pytest.mark.parametrize(
    ("value", "ratio", "expected"),
    [
        (0.16, 0.95 * 0.16, "reproduced"),  # H4-impact-force: 7.6 N / 50 N
        (0.16, 1.05 * 0.16, "not reproduced"),  # 8.4 N / 50 N
        (2.0, 0.95 * 2.0, "reproduced"),  # a bound above 1: a ratio of 1.9 is within it
        (2.0, 1.05 * 2.0, "not reproduced"),
    ],
)
def test_ratio_at_most_is_judged_against_its_value(
    value: float, ratio: float, expected: str
) -> None:
    """``ratio_at_most``: a / b <= value. A ratio 5 % below the claim's value reproduces and
    5 % above does not, for a value below 1 and one above 1, so a rule that drops the value
    (compares with 1, or a with b) gets two of the four wrong."""
    claim = {"compare": "ratio_at_most", "value": value}
    assert verdict(claim, full=ratio * 50.0) == expected


@pytest.mark.parametrize(
    ("compare", "value", "measured", "expected"),
    [
        ("at_most", 8.0, 8.0, "reproduced"),  # H4-impact-force-full-absolute, met exactly
        ("at_most", 8.0, 8.8, "not reproduced"),  # exceeded by 10 %
        ("at_least", 50.0, 50.0, "reproduced"),  # H4-impact-force-baseline-absolute
        ("at_least", 50.0, 45.0, "not reproduced"),  # 10 % short
    ],
)
def test_bounds_hold_at_the_value_and_not_beyond_it(
    compare: str, value: float, measured: float, expected: str
) -> None:
    """``at_most`` / ``at_least``: a <= value / a >= value, with no slack. A bound met exactly
    holds (the module's rule: bounds hold at equality); missed by 10 % it does not. Any slack of
    10 % or more would call the misses reproduced."""
    claim = {"compare": compare, "value": value, "b": None}
    assert verdict(claim, full=measured) == expected

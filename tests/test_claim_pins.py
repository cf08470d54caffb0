"""Pins on the verdict rules of ``ccm.reporting.claims`` (issue #18, item 7, "Nothing else pins
these").

A bound or ratio that is read loosely turns a failing claim into a reproduced one. These tests
put the compared quantity just inside and just outside each rule's ``value`` and check that
the verdict follows it, over five seeds that all agree (so the verdict is the rule's alone,
not the seeds' spread).
"""

from __future__ import annotations

from collections.abc import Sequence
from typing import Any

import pytest

from ccm.reporting.claims import evaluate, parse_claim

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


def test_less_than_is_strict() -> None:
    """Equal values are not ``a < b`` (a rule that lets a tie hold passes a null result)."""
    assert verdict({"compare": "less_than"}, full=50.0) == "not reproduced"
    assert verdict({"compare": "less_than"}, full=49.0) == "reproduced"


@pytest.mark.parametrize(
    ("measured", "expected"),
    [(3.0 * 0.9 + 50.0, "reproduced"), (3.0 * 1.1 + 50.0, "not reproduced")],
)
def test_difference_at_most_has_no_slack(measured: float, expected: str) -> None:
    """``difference_at_most 3``: a − b 10 % inside and outside the bound."""
    assert verdict({"compare": "difference_at_most", "value": 3.0}, full=measured) == expected


@pytest.mark.parametrize(("off", "expected"), [(0.9, "reproduced"), (1.1, "not reproduced")])
def test_within_uses_its_tolerance_exactly(off: float, expected: str) -> None:
    """``within 8 ± 15 %``: 10 % inside and outside the 1.2 N tolerance."""
    claim = {"compare": "within", "value": 8.0, "tolerance": 0.15, "b": None}
    assert verdict(claim, full=8.0 + off * 1.2) == expected


def test_a_requirement_holds_its_upper_bound() -> None:
    """``requires`` with at_most: a run above it does not count (the mechanism is pinned)."""
    req = [{"condition": "full", "metric": "peak_impact_force_N", "at_least": 1.0, "at_most": 10.0}]
    claim = {"compare": "at_most", "value": 20.0, "b": None, "requires": req}
    assert verdict(claim, full=9.0) == "reproduced"
    assert verdict(claim, full=15.0) == "not reproduced"


def test_the_interval_is_students_t_with_the_sample_std() -> None:
    """Five margins 1, 2, 3, 4, 5: mean 3, sample std sqrt(2.5), t(4) = 2.776, half-width
    2.776 sqrt(2.5) / sqrt(5) = 1.963 (a quantile one row off, or ddof 0, changes it)."""
    from ccm.reporting.claim_stats import mean_ci, t95

    assert t95(5) == pytest.approx(2.776) and t95(2) == pytest.approx(12.706)
    mean, ci = mean_ci([1.0, 2.0, 3.0, 4.0, 5.0])
    assert mean == 3.0 and ci == pytest.approx(2.776 * 2.5**0.5 / 5**0.5)

"""Pins on the verdict rules of ``ccm.reporting.claims`` (issue #18, item 7, "Nothing else pins
these").

A bound or ratio that is read loosely turns a failing claim into a reproduced one. These tests
put the compared quantity just inside and just outside each rule's ``value`` and check that
the verdict follows it, over five seeds that all agree (so the verdict is the rule's alone,
not the seeds' spread).
"""

from __future__ import annotations

import math
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


def _runs(values: dict[str, dict[str, float]], n: int = SEEDS) -> list[dict[str, Any]]:
    """``n`` ok runs of experiment ``e`` (seeds 0..n-1) that all measured ``values``."""
    run = {"experiment": "e", "status": "ok", "conditions": values, "trials": []}
    return [{**run, "seed": seed} for seed in range(n)]


def _positive(m: float) -> bool:
    """A strict claim's test of a margin."""
    return m > 0


def verdict(claim: dict[str, Any], full: float, baseline: float = 50.0) -> str:
    """The verdict of ``claim`` over :data:`SEEDS` ok runs that all measured ``full`` and
    ``baseline`` as the two conditions' ``peak_impact_force_N``."""
    c = parse_claim({**BASE, **claim}, "claims[0]")
    values = {"full": {"peak_impact_force_N": full}, "baseline": {"peak_impact_force_N": baseline}}
    return evaluate(c, _runs(values)).verdict


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
    from ccm.core.stats import mean_ci, t95

    assert t95(5) == pytest.approx(2.776) and t95(2) == pytest.approx(12.706)
    mean, ci = mean_ci([1.0, 2.0, 3.0, 4.0, 5.0])
    assert mean == 3.0 and ci == pytest.approx(2.776 * 2.5**0.5 / 5**0.5)


def test_the_t_quantile_table_ends_at_30_degrees_of_freedom() -> None:
    """t(29) = 2.045 and t(30) = 2.042 are the table's last rows; 31 and more degrees of
    freedom take the normal 1.96; one sample has no quantile. Two margins 1 and 3: mean 2,
    half-width t(1) sqrt(2) / sqrt(2) = 12.706 (an interval, not the one-seed rule)."""
    from ccm.core.stats import mean_ci, t95

    assert t95(30) == pytest.approx(2.045) and t95(31) == pytest.approx(2.042)
    assert t95(32) == 1.96 and t95(500) == 1.96 and math.isnan(t95(1))
    mean, ci = mean_ci([1, 3])
    assert mean == 2.0 and ci == pytest.approx(12.706)
    mean, ci = mean_ci([4.0])
    assert mean == 4.0 and math.isnan(ci)


def test_the_rule_text_names_the_case() -> None:
    """One seed: its margin; two or more that differ: the t-interval; two or more identical:
    one deterministic run (so even two equal seeds are not called an interval)."""
    from ccm.reporting.claim_stats import decide

    assert decide([0.5], _positive).rule == "one seed: its margin"
    assert decide([0.5, 0.7], _positive).rule == "95 % t-interval of the mean margin"
    two = decide([0.5, 0.5], _positive)
    assert two.verdict == "reproduced" and two.rule.startswith("the 2 runs are identical")
    assert decide([-0.5, -0.5], _positive, "sign").verdict == "not reproduced"
    with pytest.raises(ValueError, match="no margins"):
        decide([], _positive)


def test_the_sign_test_needs_more_than_half_for_partially() -> None:
    """10 runs: 5 holding is no majority (not reproduced), 6 is (p = 0.377: partially), 9 is
    p = 0.0107 < 0.05 (reproduced); P(X >= k) for k > n is refused, not 0."""
    from ccm.reporting.claim_stats import decide, sign_test_p

    def margins(k: int) -> list[float]:
        return [0.1 * (i + 1) for i in range(k)] + [-0.1 * (i + 1) for i in range(10 - k)]

    assert decide(margins(5), _positive, "sign").verdict == "not reproduced"
    six = decide(margins(6), _positive, "sign")
    assert six.verdict == "partially" and "p = 0.377" in six.rule
    assert decide(margins(9), _positive, "sign").verdict == "reproduced"
    assert sign_test_p(6, 10) == pytest.approx(386 / 1024)
    with pytest.raises(ValueError, match="need 0 <= k <= n, got k=11, n=10"):
        sign_test_p(11, 10)


def test_a_changed_from_requirement_bounds_the_relative_change() -> None:
    """``changed_from``: |a / b − 1| must lie in [at_least, at_most], both ends inclusive.
    Against b = 4: a = 5 and a = 3 give 0.25 (the lower bound), 6 gives 0.5 (the upper one),
    4.4 gives 0.1 and 8 gives 1.0 (outside); 10 against 8 is 0.25 (a ratio: the difference,
    2, is outside); a reference of 0 cannot be changed from."""
    req = [{"condition": "full", "metric": "d", "at_least": 0.25, "at_most": 0.5,
            "changed_from": {"condition": "baseline", "metric": "d"}}]  # fmt: skip
    claim = {"compare": "at_most", "value": 20.0, "b": None, "requires": req}
    c = parse_claim({**BASE, **claim}, "claims[0]")

    def judged(full: float, base: float) -> str:
        values = {"full": {"peak_impact_force_N": 10.0, "d": full}, "baseline": {"d": base}}
        return evaluate(c, _runs(values)).verdict

    assert judged(5.0, 4.0) == judged(3.0, 4.0) == judged(6.0, 4.0) == "reproduced"
    assert judged(4.4, 4.0) == judged(8.0, 4.0) == "not reproduced"
    assert judged(10.0, 8.0) == "reproduced"
    assert judged(0.1, 0.0) == "not reproduced"


def test_the_reported_quantity_is_the_compared_one() -> None:
    """The verdict's mean is the quantity the rule compares: a − b for less_than, a / b for
    ratio_within, with its interval; one seed has none; a seed without values is missing."""
    less = parse_claim({**BASE, "compare": "less_than"}, "claims[0]")
    v = evaluate(less, _runs({"full": {"peak_impact_force_N": 8.0},
                              "baseline": {"peak_impact_force_N": 50.0}}))  # fmt: skip
    assert v.mean == pytest.approx(-42.0) and v.ci95 == 0.0 and v.n_seeds == SEEDS
    ratio = parse_claim({**BASE, "compare": "ratio_within", "value": 0.2, "tolerance": 0.1},
                        "claims[0]")  # fmt: skip
    values = {"full": {"peak_impact_force_N": 8.0}, "baseline": {"peak_impact_force_N": 40.0}}
    v = evaluate(ratio, _runs(values, 1))
    assert v.mean == pytest.approx(0.2) and v.ci95 is None and v.verdict == "reproduced"
    v = evaluate(ratio, _runs({**values, "baseline": {"peak_impact_force_N": 0.0}}))
    assert v.verdict == "not measured" and v.n_seeds == 0 and v.mean is None


def test_a_non_finite_metric_is_missing_not_a_value() -> None:
    """A NaN or infinite metric makes the run's claim not measured (never a margin)."""
    c = parse_claim({**BASE, "compare": "at_most", "value": 20.0, "b": None}, "claims[0]")
    for bad in (math.nan, math.inf):
        v = evaluate(c, _runs({"full": {"peak_impact_force_N": bad}}))
        assert v.verdict == "not measured"
    assert evaluate(c, _runs({"full": {"peak_impact_force_N": 5.0}})).verdict == "reproduced"


def test_the_report_line_spells_out_what_was_compared() -> None:
    """The verdict's text, which the report prints, names the compared quantity with its
    interval, both values, the holding runs, the rule and each requirement as written:
    ``a − b`` for less_than, ``a / b`` for a ratio, ``|a| (trial k)`` for a trial's
    magnitude, bounds with their infinite sides left out."""
    req = [{"condition": "full", "metric": "d", "at_least": 0.25,
            "changed_from": {"condition": "baseline", "metric": "d"}},
           {"condition": "full", "metric": "d", "at_most": 9.0}]  # fmt: skip
    less = parse_claim({**BASE, "compare": "less_than", "requires": req}, "claims[0]")
    base = {"peak_impact_force_N": 50.0, "d": 4.0}
    values = [{"full": {"peak_impact_force_N": f, "d": 5.0}, "baseline": base} for f in (8.0, 10.0)]
    runs = [{"experiment": "e", "status": "ok", "conditions": v, "trials": []} for v in values]
    v = evaluate(less, runs)
    assert v.ours == (
        "full.peak_impact_force_N − baseline.peak_impact_force_N = -41 ± 13 (n = 2) "
        "(full.peak_impact_force_N = 9, baseline.peak_impact_force_N = 50); holds in 2 of 2 "
        "runs; rule: 95 % t-interval of the mean margin; requires "
        "0.25 <= |full.d / baseline.d − 1|, full.d <= 9: met in 2 of 2"
    )  # fmt: skip
    assert v.ci95 == pytest.approx(12.706) and v.n_seeds == 2
    ratio = parse_claim({**BASE, "compare": "ratio_at_most", "value": 0.5}, "claims[0]")
    assert evaluate(ratio, runs[:1]).ours.startswith(
        "full.peak_impact_force_N / baseline.peak_impact_force_N = 0.16 (n = 1, one seed: "
        "no interval) (full.peak_impact_force_N = 8, baseline.peak_impact_force_N = 50)"
    )  # fmt: skip
    trial = parse_claim({**BASE, "compare": "at_most", "value": 1.0, "b": None,
                         "a": {"condition": "full", "metric": "err", "trial": 3, "abs": True}},
                        "claims[0]")  # fmt: skip
    assert str(trial.a) == "|full.err| (trial 3)" and trial.b is None
    assert (less.value, less.tolerance, less.note, less.discussion) == (None, None, "", "")


def test_a_failed_run_without_a_task_counts_against_every_task() -> None:
    """A sweep over tasks: a claim of task T is judged on T's runs; a failed run that does not
    say its task (it failed before writing it) may have been T's, so the claim is not
    measured; an ok run of another task, or a failed run that names another task, is not
    T's. A run without the claim's condition is missing, not an error."""
    c = parse_claim({**BASE, "compare": "at_most", "value": 20.0, "b": None, "task": "T"}, "c")
    ok = {"experiment": "e", "status": "ok", "task": "T", "trials": [],
          "conditions": {"full": {"peak_impact_force_N": 5.0}}}  # fmt: skip
    other = {**ok, "task": "U", "conditions": {"full": {"peak_impact_force_N": 50.0}}}
    assert evaluate(c, [ok, other]).verdict == "reproduced"
    assert evaluate(c, [ok, {"experiment": "e", "status": "failed", "task": "U"}]).n_seeds == 1
    v = evaluate(c, [ok, {"experiment": "e", "status": "failed"}])
    assert v.verdict == "not measured" and v.ours.startswith("1 of 2 runs missing")
    assert evaluate(c, [{**ok, "conditions": {}}]).verdict == "not measured"


def test_labels_equality_and_missing_trials() -> None:
    """A ratio bound is strict (a ratio equal to it does not hold) while a difference bound
    holds at equality; each comparison is labelled by its quantity; a trial that a run does
    not have, or a run without the claim's task, gives no value."""
    one = {"full": {"peak_impact_force_N": 8.0}, "baseline": {"peak_impact_force_N": 40.0}}
    ratio = parse_claim({**BASE, "compare": "ratio_at_most", "value": 0.2}, "c")
    assert evaluate(ratio, _runs(one)).verdict == "not reproduced"  # 0.2 is not < 0.2
    diff = parse_claim({**BASE, "compare": "difference_at_most", "value": -32.0}, "c")
    v = evaluate(diff, _runs(one))
    assert v.verdict == "reproduced"  # −32 <= −32
    assert v.ours.startswith("full.peak_impact_force_N − baseline.peak_impact_force_N = -32 ")
    within = parse_claim({**BASE, "compare": "ratio_within", "value": 0.2, "tolerance": 0.5}, "c")
    assert evaluate(within, _runs(one)).ours.startswith("full.peak_impact_force_N / baseline.")
    at_most = parse_claim({**BASE, "compare": "at_most", "value": 9.0, "b": None}, "c")
    v = evaluate(at_most, _runs(one, 1))
    assert v.ours.startswith("full.peak_impact_force_N = 8 (n = 1, one seed: no interval); ")
    trial = parse_claim({**BASE, "compare": "at_most", "value": 9.0, "b": None,
                         "a": {"condition": "full", "metric": "f", "trial": 2}}, "c")  # fmt: skip
    rows = [{"condition": "full", "trial": 1, "f": 1.0}]
    run = {"experiment": "e", "status": "ok", "conditions": {}, "trials": rows}
    v = evaluate(trial, [run])
    assert (v.verdict, v.ours, v.n_seeds) == ("not measured", "–", 0)
    assert evaluate(trial, [{**run, "trials": [*rows, {**rows[0], "trial": 2}]}]).mean == 1.0
    tasked = parse_claim({**BASE, "compare": "at_most", "value": 9.0, "b": None, "task": "T"}, "c")
    untasked_ok = {"experiment": "e", "status": "ok", "conditions": one, "trials": []}
    assert evaluate(tasked, [untasked_ok]).verdict == "not measured"

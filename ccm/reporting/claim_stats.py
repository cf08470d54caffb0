"""The statistics behind a claim's verdict over seeds (issue #18 item 6; used by
:mod:`ccm.reporting.claims`).

Each seed gives a *margin*, positive when the claim holds in that run. Two rules turn the
margins of n seeds into a verdict:

* **t-interval** (the default): the 95 % Student-t interval of the mean margin. The claim is
  *reproduced* when the whole interval lies on the claim's side, *partially* when only the mean
  does. One seed: the margin itself, no interval.
* **sign test**, used instead when the margins are clearly not normal (n ≥ 3 and the
  Shapiro–Wilk test rejects normality at 5 %): a heavy tail can put a mean's interval across
  zero although the claim holds in every run (H3's one-step against long-horizon error held in
  5 of 5 seeds and read "partially"). The claim is *reproduced* when the one-sided binomial
  probability of at least k holding runs out of n under a fair coin is below 5 % (n = 5 needs
  5 of 5), *partially* when more than half hold.

A claim may fix the **sign test** as its rule (``test: sign`` in claims.yaml), written before
its runs (issue #38: where the paper gives no number, the bound, the seeds and the test are
stated in advance); n = 10 then needs 9 holding runs (p = 0.011; 8 of 10 gives p = 0.055).

Runs whose margins are all **identical** (a deterministic protocol: seed A §4.1's noiseless
world, or a controller that never reads the noisy sensor) are one run repeated, not n
replicates: the verdict is that one run's margin, whichever rule the claim names, and the
report says so (a sign test over copies would claim a p-value no experiment earned).

:func:`decide` applies the rule and says which one decided (the report shows it).
"""

from __future__ import annotations

import math
from collections.abc import Callable, Sequence
from dataclasses import dataclass

import numpy as np

# two-sided 95 % Student-t quantiles for 1..30 degrees of freedom (larger: normal 1.96)
_T95 = (12.706, 4.303, 3.182, 2.776, 2.571, 2.447, 2.365, 2.306, 2.262, 2.228, 2.201, 2.179,
        2.160, 2.145, 2.131, 2.120, 2.110, 2.101, 2.093, 2.086, 2.080, 2.074, 2.069, 2.064,
        2.060, 2.056, 2.052, 2.048, 2.045, 2.042)  # fmt: skip
ALPHA = 0.05  # the level of both rules and of the normality test
#: a claim's ``test``: ``auto`` (t-interval, or the sign test for clearly non-normal margins)
#: or ``sign`` (the sign test whatever the margins' shape)
TESTS = ("auto", "sign")


def t95(n: int) -> float:
    """Two-sided 95 % Student-t quantile for the mean of ``n`` samples (NaN if n < 2)."""
    if n < 2:
        return math.nan
    return _T95[n - 2] if n - 1 <= len(_T95) else 1.96


def mean_ci(x: Sequence[float]) -> tuple[float, float]:
    """Mean and 95 % t-interval half-width; one value: no interval (NaN)."""
    arr = np.asarray(x, dtype=float)
    if arr.size < 2:
        return float(arr.mean()), math.nan
    return float(arr.mean()), float(t95(arr.size) * arr.std(ddof=1) / math.sqrt(arr.size))


def sign_test_p(k: int, n: int) -> float:
    """One-sided binomial tail P(X >= k) for X ~ Bin(n, 1/2): how likely k or more of n runs
    hold if holding were a coin flip."""
    if not 0 <= k <= n:
        raise ValueError(f"need 0 <= k <= n, got k={k}, n={n}")
    return sum(math.comb(n, i) for i in range(k, n + 1)) / 2.0**n


def normality_p(x: Sequence[float]) -> float | None:
    """Shapiro–Wilk p-value of ``x``; None when it cannot be computed (n < 3, or all equal)."""
    arr = np.asarray(x, dtype=float)
    if arr.size < 3 or float(np.ptp(arr)) == 0.0:
        return None
    from scipy.stats import shapiro

    return float(shapiro(arr).pvalue)


@dataclass(frozen=True)
class Decision:
    """A verdict over seeds and the rule that gave it (module docstring)."""

    verdict: str  # reproduced | partially | not reproduced
    rule: str  # human-readable, for the report


def _sign_test(margins: Sequence[float], holds: Callable[[float], bool], why: str) -> Decision:
    """The sign test over ``margins``; ``why`` says why it decides (for the report)."""
    n = len(margins)
    k = sum(holds(m) for m in margins)
    p = sign_test_p(k, n)
    verdict = "reproduced" if p < ALPHA else "partially" if 2 * k > n else "not reproduced"
    return Decision(verdict, f"sign test ({k} of {n} hold, p = {p:.3g}; {why})")


def decide(
    margins: Sequence[float], holds: Callable[[float], bool], test: str = "auto"
) -> Decision:
    """The verdict for per-seed ``margins`` (``holds(m)``: the claim holds at margin m; strict
    or not at 0 as the comparison asks); ``test``: one of :data:`TESTS`."""
    n = len(margins)
    if n == 0:
        raise ValueError("no margins")
    if test not in TESTS:
        raise ValueError(f"test must be one of {TESTS}, got {test!r}")
    if n >= 2 and float(np.ptp(np.asarray(margins, dtype=float))) == 0.0:
        verdict = "reproduced" if holds(margins[0]) else "not reproduced"
        return Decision(
            verdict, f"the {n} runs are identical (deterministic): one run's margin, no spread"
        )
    if test == "sign":
        return _sign_test(margins, holds, "the claim's rule")
    p_norm = normality_p(margins)
    if p_norm is not None and p_norm < ALPHA:
        return _sign_test(margins, holds, f"margins not normal, Shapiro–Wilk p = {p_norm:.2g}")
    mean, ci = mean_ci(margins)
    lower = mean - (0.0 if math.isnan(ci) else ci)
    verdict = "reproduced" if holds(lower) else "partially" if holds(mean) else "not reproduced"
    rule = "one seed: its margin" if n < 2 else "95 % t-interval of the mean margin"
    return Decision(verdict, rule)

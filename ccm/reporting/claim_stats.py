"""The statistics behind a claim's verdict over seeds (issue #18 item 6; used by
:mod:`ccm.reporting.claims`).

Each seed gives a *margin*, positive when the claim holds in that run. A claim's rule is
fixed in advance, in claims.yaml, never chosen from its margins (issue #38):

* **t-interval** (``test: t``, the default): the 95 % Student-t interval of the mean margin.
  The claim is *reproduced* when the whole interval lies on the claim's side, *partially*
  when only the mean does. One seed: the margin itself, no interval. A heavy tail can put
  the interval across zero although the claim holds in every run; that is this rule's cost,
  and it is paid rather than switching rules after the margins are seen.
* **sign test** (``test: sign``, written before the claim's runs, over the
  :data:`SIGN_TEST_RUNS` = 10 seeds of its experiment): *reproduced* when the one-sided
  binomial probability of at least k holding runs out of n under a fair coin is below 5 %
  (9 of 10: p = 0.011; 8 of 10 gives p = 0.055), *partially* when more than half hold. With
  fewer runs (a quick run, seed 0 only) the rule cannot reach the level it was fixed for, and
  the verdict is at most *partially*.

Until issue #38 the t-interval gave way to the sign test whenever Shapiro–Wilk rejected the
margins' normality. That choice looked at the margins, and at n = 5 the sign test it chose
needs all 5 seeds, so one seed decided a verdict (held-out seeds 40–44 differed from 0–4 so).

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

from ccm.core.stats import mean_ci

ALPHA = 0.05  # the level of both rules
#: a claim's ``test``, fixed in advance: ``t`` (the t-interval) or ``sign`` (the sign test)
TESTS = ("t", "sign")
#: the number of runs a ``test: sign`` claim is fixed for (issue #38: "use 10 seeds where a
#: sign test decides"); its experiment sweeps at least this many seeds
SIGN_TEST_RUNS = 10


def sign_test_p(k: int, n: int) -> float:
    """One-sided binomial tail P(X >= k) for X ~ Bin(n, 1/2): how likely k or more of n runs
    hold if holding were a coin flip."""
    if not 0 <= k <= n:
        raise ValueError(f"need 0 <= k <= n, got k={k}, n={n}")
    return sum(math.comb(n, i) for i in range(k, n + 1)) / 2.0**n


@dataclass(frozen=True)
class Decision:
    """A verdict over seeds and the rule that gave it (module docstring)."""

    verdict: str  # reproduced | partially | not reproduced
    rule: str  # human-readable, for the report


def _sign_test(margins: Sequence[float], holds: Callable[[float], bool]) -> Decision:
    """The claim's sign test over ``margins`` (module docstring)."""
    n = len(margins)
    k = sum(holds(m) for m in margins)
    p = sign_test_p(k, n)
    verdict = "reproduced" if p < ALPHA else "partially" if 2 * k > n else "not reproduced"
    if n < SIGN_TEST_RUNS:
        verdict = "partially" if verdict == "reproduced" else verdict
        why = f"fewer than the {SIGN_TEST_RUNS} runs the rule is fixed for: at most partially"
    else:
        why = "the claim's rule"
    return Decision(verdict, f"sign test ({k} of {n} hold, p = {p:.3g}; {why})")


def decide(margins: Sequence[float], holds: Callable[[float], bool], test: str = "t") -> Decision:
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
        return _sign_test(margins, holds)
    mean, ci = mean_ci(margins)
    lower = mean - (0.0 if math.isnan(ci) else ci)
    verdict = "reproduced" if holds(lower) else "partially" if holds(mean) else "not reproduced"
    rule = "one seed: its margin" if n < 2 else "95 % t-interval of the mean margin"
    return Decision(verdict, rule)

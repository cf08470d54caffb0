"""The papers' claims as data, and their verdicts against measured runs (issue #8, part 1).

``experiments/claims.yaml`` lists each claim: the experiment and the ``summary.json`` values
it is judged on, a comparison, the paper's own value and its source (figure, table,
section). :func:`load_claims` validates the file; :func:`evaluate` judges one claim against
the summaries of several seeds.

A *reference* names one number of a summary: ``{condition, metric}`` for the condition's
value (``conditions.<condition>.<metric>``), plus ``trial: N`` for one trial's value
(``trials`` entry with that condition and trial number). Comparisons (per seed, then over
seeds):

* ``less_than``: ``a < b`` (``a``, ``b`` references);
* ``ratio_at_most``: ``a / b <= value``;
* ``at_most`` / ``at_least``: ``a <= value`` / ``a >= value``;
* ``difference_at_most``: ``a − b <= value`` (e.g. a time cost in seconds);
* ``within``: ``|a − value| <= tolerance · |value|`` (``tolerance`` a fraction, e.g. 0.15);
* ``ratio_within``: ``|a / b − value| <= tolerance · |value|`` (e.g. "proportional": 2.0 ± 25 %).

Verdict over n seeds, from d = the per-seed margin (``b − a``, ``value − a/b``,
``value − a``, ``a − value``, ``value − (a − b)``, ``tolerance · |value| − |a − value|`` or
the same with a / b; positive when the claim holds; ≥ 0 suffices for the bounds ``at_most``,
``at_least``, ``difference_at_most``, ``within`` and ``ratio_within``, which hold at
equality): :func:`ccm.reporting.claim_stats.decide`,
the 95 % t-interval of the mean margin, or the sign test where the claim names it; the
report says which rule decided. A reference may take the metric's magnitude
(``abs: true``: a signed error against a bound); ``condition: run_info`` reads one of the run's
scalar wall-clock facts that ``ccm report`` joins from run_info.json. Every run of the
claim's experiment must be ``ok`` and give its values: otherwise the claim is **not
measured**, and the text says how many runs are missing and what the measured ones give.
For a comparison of two references the text shows both values next to the ratio or
difference.

A claim about a mechanism may name ``requires``: references with bounds
(``{condition, metric, at_least, at_most}``) that show the mechanism acting in a run, e.g.
AVIC's stiffness moving at all (``stiffness_active_frac``). A requirement with
``changed_from: {condition, metric}`` bounds the relative change ``|a / b − 1|`` of its value
against that reference instead (e.g. a cost term that must move the impedance by ≥ 5 %, in
either direction, before "unchanged" can mean anything). ``task`` restricts a claim to the
runs of one task of a sweep over tasks. A run that misses a requirement
does not count as holding; if no run meets the requirements the claim is **not reproduced**,
and if only some do, a *reproduced* verdict becomes **partially**.

``test: sign`` fixes the verdict's rule to the sign test over 10 seeds (written before the
runs; see :mod:`ccm.reporting.claim_stats`), instead of the t-interval (``test: t``, the
default). ``diagnostic: true`` marks a claim
judged on a protocol other than the paper's (a robustness row, e.g. H1 under sensor noise
beside seed A §4.1's noiseless one): the report shows its verdict but does not count it in
the tally.
"""

from __future__ import annotations

import math
from collections.abc import Mapping, Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

from ccm.core.errors import ConfigError, check_keys
from ccm.core.stats import mean_ci
from ccm.reporting.claim_stats import TESTS, decide

COMPARISONS = (
    "less_than", "ratio_at_most", "at_most", "at_least", "difference_at_most", "within",
    "ratio_within",
)  # fmt: skip
_TWO_REFS = ("less_than", "ratio_at_most", "difference_at_most", "ratio_within")
_WITHIN = ("within", "ratio_within")  # value ± tolerance × |value|
_CLAIM_KEYS = ("id", "paper", "source", "statement", "paper_value", "experiment", "compare",
               "a", "b", "value", "tolerance", "figures", "note", "discussion", "requires",
               "task", "test", "diagnostic")  # fmt: skip
_REF_KEYS = ("condition", "metric", "trial", "abs")
#: the pseudo-condition of a run's scalar wall-clock facts (run_info.json, joined by ccm report)
RUN_INFO = "run_info"
_REQ_KEYS = (*_REF_KEYS, "at_least", "at_most", "changed_from")


@dataclass(frozen=True)
class Ref:
    """One number of a summary: a condition's metric, or one trial's."""

    condition: str
    metric: str
    trial: int | None = None
    absolute: bool = False  # YAML ``abs``: the metric's magnitude (a signed error vs a bound)

    def value(self, summary: Mapping[str, Any]) -> float | None:
        if self.condition == RUN_INFO:
            v = (summary.get(RUN_INFO) or {}).get(self.metric)
        elif self.trial is None:
            v = (summary.get("conditions") or {}).get(self.condition, {}).get(self.metric)
        else:
            rows = [
                t
                for t in summary.get("trials") or []
                if t.get("condition") == self.condition and t.get("trial") == self.trial
            ]
            v = rows[0].get(self.metric) if rows else None
        if not isinstance(v, int | float) or isinstance(v, bool) or not math.isfinite(v):
            return None
        return abs(float(v)) if self.absolute else float(v)

    def __str__(self) -> str:
        t = f" (trial {self.trial})" if self.trial is not None else ""
        name = f"{self.condition}.{self.metric}"
        return f"|{name}|{t}" if self.absolute else f"{name}{t}"


@dataclass(frozen=True)
class Requirement:
    """A reference that must lie in [at_least, at_most] for a run to count (module doc)."""

    ref: Ref
    at_least: float = -math.inf
    at_most: float = math.inf
    changed_from: Ref | None = None  # bound |ref / changed_from − 1| instead of ref

    def met(self, summary: Mapping[str, Any]) -> bool:
        v = self.ref.value(summary)
        if v is not None and self.changed_from is not None:
            b = self.changed_from.value(summary)
            v = None if b is None or b == 0.0 else abs(v / b - 1.0)
        return v is not None and self.at_least <= v <= self.at_most

    def __str__(self) -> str:
        lo = "" if math.isinf(self.at_least) else f"{self.at_least:g} <= "
        hi = "" if math.isinf(self.at_most) else f" <= {self.at_most:g}"
        what = str(self.ref)
        if self.changed_from is not None:
            what = f"|{self.ref} / {self.changed_from} − 1|"
        return f"{lo}{what}{hi}"


@dataclass(frozen=True)
class Claim:
    """A paper's claim and how ccm judges it (module docstring)."""

    id: str
    paper: str
    source: str
    statement: str
    paper_value: str
    experiment: str
    compare: str
    a: Ref
    b: Ref | None = None
    value: float | None = None
    tolerance: float | None = None  # ``within`` / ``ratio_within``: a fraction of |value|
    figures: tuple[str, ...] = ()
    note: str = ""
    discussion: str = ""  # the protocol note that discusses the outcome (experiments/*.md)
    requires: tuple[Requirement, ...] = ()
    task: str | None = None  # judge only the runs of this task (summary.json ``task``)
    test: str = "t"  # the verdict's rule over seeds: t | sign (claim_stats.TESTS)
    diagnostic: bool = False  # a robustness row: shown in the report, not tallied


@dataclass
class Verdict:
    """The outcome of one claim over the seeds found."""

    claim: Claim
    verdict: str  # reproduced | partially | not reproduced | not measured
    ours: str  # human-readable: mean ± 95 % CI of the compared quantity
    mean: float | None
    ci95: float | None
    n_seeds: int


def _ref(key: str, d: Any) -> Ref:
    if not isinstance(d, Mapping):
        raise ConfigError(key, "must be a mapping {condition, metric[, trial]}")
    check_keys(key, d, _REF_KEYS)
    for k in ("condition", "metric"):
        if not isinstance(d.get(k), str) or not d[k]:
            raise ConfigError(f"{key}.{k}", "is required (a non-empty string)")
    trial = d.get("trial")
    if trial is not None and (isinstance(trial, bool) or not isinstance(trial, int) or trial < 1):
        raise ConfigError(f"{key}.trial", f"must be a trial number >= 1, got {trial!r}")
    absolute = d.get("abs", False)
    if not isinstance(absolute, bool):
        raise ConfigError(f"{key}.abs", f"must be true or false, got {absolute!r}")
    return Ref(d["condition"], d["metric"], trial, absolute)


def _requirement(key: str, d: Any) -> Requirement:
    if not isinstance(d, Mapping):
        raise ConfigError(key, "must be a mapping {condition, metric, at_least and/or at_most}")
    check_keys(key, d, _REQ_KEYS)
    bounds = {}
    for k in ("at_least", "at_most"):
        v = d.get(k)
        if v is not None:
            if isinstance(v, bool) or not isinstance(v, int | float) or not math.isfinite(v):
                raise ConfigError(f"{key}.{k}", f"must be a finite number, got {v!r}")
            bounds[k] = float(v)
    if not bounds:
        raise ConfigError(key, "needs at_least and/or at_most")
    ref = _ref(key, {k: v for k, v in d.items() if k in _REF_KEYS})
    base = d.get("changed_from")
    base_ref = None if base is None else _ref(f"{key}.changed_from", base)
    return Requirement(ref, changed_from=base_ref, **bounds)


def parse_claim(d: Any, key: str) -> Claim:
    """Validate one claim mapping; every error names its key."""
    if not isinstance(d, Mapping):
        raise ConfigError(key, "must be a mapping")
    check_keys(key, d, _CLAIM_KEYS)
    for k in ("id", "paper", "source", "statement", "paper_value", "experiment", "compare"):
        if not isinstance(d.get(k), str | int | float) or d.get(k) == "":
            raise ConfigError(f"{key}.{k}", "is required")
    if d["paper"] not in ("seed_a", "seed_b"):
        raise ConfigError(f"{key}.paper", f"must be seed_a or seed_b, got {d['paper']!r}")
    compare = d["compare"]
    if compare not in COMPARISONS:
        raise ConfigError(f"{key}.compare", f"must be one of {', '.join(COMPARISONS)}")
    a = _ref(f"{key}.a", d.get("a"))
    b = _ref(f"{key}.b", d.get("b")) if compare in _TWO_REFS else None
    value = None
    if compare != "less_than":
        v = d.get("value")
        if isinstance(v, bool) or not isinstance(v, int | float) or not math.isfinite(v):
            raise ConfigError(f"{key}.value", f"a finite number is required for {compare}")
        value = float(v)
    tolerance = None
    if compare in _WITHIN:
        tol = d.get("tolerance")
        if isinstance(tol, bool) or not isinstance(tol, int | float) or not 0 < tol < math.inf:
            raise ConfigError(
                f"{key}.tolerance", f"a fraction > 0 is required for {compare}, got {tol!r}"
            )
        tolerance = float(tol)
    elif d.get("tolerance") is not None:
        raise ConfigError(
            f"{key}.tolerance", f"is only used with compare: within or ratio_within, not {compare}"
        )
    figures = d.get("figures") or []
    if not isinstance(figures, list) or not all(isinstance(f, str) for f in figures):
        raise ConfigError(f"{key}.figures", "must be a list of figure file names")
    reqs = d.get("requires") or []
    if not isinstance(reqs, list):
        raise ConfigError(f"{key}.requires", "must be a list of {condition, metric, bounds}")
    requires = tuple(_requirement(f"{key}.requires[{i}]", r) for i, r in enumerate(reqs))
    test = d.get("test", "t")
    if test not in TESTS:
        raise ConfigError(f"{key}.test", f"must be one of {', '.join(TESTS)}, got {test!r}")
    diagnostic = d.get("diagnostic", False)
    if not isinstance(diagnostic, bool):
        raise ConfigError(f"{key}.diagnostic", f"must be true or false, got {diagnostic!r}")
    return Claim(
        id=str(d["id"]), paper=d["paper"], source=str(d["source"]),
        statement=str(d["statement"]), paper_value=str(d["paper_value"]),
        experiment=str(d["experiment"]), compare=compare, a=a, b=b, value=value,
        tolerance=tolerance,
        figures=tuple(figures), note=str(d.get("note", "")),
        discussion=str(d.get("discussion", "")), requires=requires,
        task=None if d.get("task") is None else str(d["task"]),
        test=test, diagnostic=diagnostic,
    )  # fmt: skip


def load_claims(path: Path) -> list[Claim]:
    """Read and validate a claims YAML file (a list under ``claims:``); ids must be unique."""
    import yaml

    try:
        data = yaml.safe_load(Path(path).read_text(encoding="utf-8"))
    except (OSError, yaml.YAMLError) as exc:
        first = str(exc).strip().splitlines()[0] if str(exc).strip() else type(exc).__name__
        raise ConfigError(str(path), f"cannot read claims: {first}") from None
    items = data.get("claims") if isinstance(data, Mapping) else None
    if not isinstance(items, list) or not items:
        raise ConfigError(f"{path}:claims", "must be a non-empty list")
    claims = [parse_claim(c, f"claims[{i}]") for i, c in enumerate(items)]
    seen: set[str] = set()
    for i, c in enumerate(claims):
        if c.id in seen:
            raise ConfigError(f"claims[{i}].id", f"duplicate id {c.id!r}")
        seen.add(c.id)
    return claims


def _margin(c: Claim, s: Mapping[str, Any]) -> tuple[float, float] | None:
    """(compared quantity, margin > 0 when the claim holds) for one seed's summary."""
    a = c.a.value(s)
    if a is None:
        return None
    if c.compare in ("at_most", "at_least"):
        assert c.value is not None
        return a, (c.value - a) if c.compare == "at_most" else (a - c.value)
    if c.compare == "within":
        assert c.value is not None and c.tolerance is not None
        return a, c.tolerance * abs(c.value) - abs(a - c.value)
    assert c.b is not None
    b = c.b.value(s)
    if b is None:
        return None
    if c.compare == "less_than":
        return a - b, b - a
    if c.compare == "difference_at_most":
        assert c.value is not None
        return a - b, c.value - (a - b)
    if b == 0.0:
        return None
    assert c.value is not None
    if c.compare == "ratio_within":
        assert c.tolerance is not None
        return a / b, c.tolerance * abs(c.value) - abs(a / b - c.value)
    return a / b, c.value - a / b


def _of_experiment(claim: Claim, summaries: Sequence[Mapping[str, Any]]) -> list[Mapping]:
    """Every run of the claim's experiment (and task), whatever its status; a failed run that
    does not say its task counts for every task of its experiment."""

    def of_task(s: Mapping[str, Any]) -> bool:
        return (
            claim.task is None
            or s.get("task", claim.task if s.get("status") != "ok" else None) == claim.task
        )

    return [s for s in summaries if s.get("experiment") == claim.experiment and of_task(s)]


def _two_values(claim: Claim, runs: Sequence[Mapping[str, Any]]) -> str:
    """ "a = …, b = …" (means over the runs) for a comparison of two references, so a ratio or
    difference never stands without the values it came from."""
    if claim.b is None:
        return ""
    parts = []
    for ref in (claim.a, claim.b):
        vals = [v for v in (ref.value(s) for s in runs) if v is not None]
        parts.append(f"{ref} = {float(np.mean(vals)):.4g}" if vals else f"{ref} = –")
    return f" ({', '.join(parts)})"


def evaluate(claim: Claim, summaries: Sequence[Mapping[str, Any]]) -> Verdict:
    """Judge ``claim`` on the runs of its experiment (one per seed; module docstring).

    Every run of the experiment must be ``ok`` and give the claim's values: a run that failed,
    or whose value is missing, makes the claim **not measured** (the text says how many runs
    are missing and what the measured ones would give), so a verdict never rests silently on
    the seeds that happened to work.
    """
    every = _of_experiment(claim, summaries)
    measured = [
        (s, p) for s, p in ((s, _margin(claim, s)) for s in every if s.get("status") == "ok")
        if p is not None
    ]  # fmt: skip
    if not measured:
        return Verdict(claim, "not measured", "–", None, None, 0)
    qty, margins = zip(*(p for _, p in measured), strict=True)
    acting = [all(r.met(s) for r in claim.requires) for s, _ in measured]
    q_mean, q_ci = mean_ci(qty)
    # a bound (at_most / at_least) holds at equality; a comparison of two values must be strict
    strict = claim.compare in ("less_than", "ratio_at_most")

    def holds(x: float) -> bool:
        return x > 0 if strict else x >= 0

    decision = decide(margins, holds, claim.test)
    verdict = decision.verdict
    if not any(acting):
        verdict = "not reproduced"
    elif not all(acting) and verdict == "reproduced":
        verdict = "partially"
    what = {
        "less_than": f"{claim.a} − {claim.b}",
        "difference_at_most": f"{claim.a} − {claim.b}",
        "ratio_at_most": f"{claim.a} / {claim.b}",
        "ratio_within": f"{claim.a} / {claim.b}",
    }
    label = what.get(claim.compare, str(claim.a))
    n = len(margins)
    spread = f"(n = {n}, one seed: no interval)" if n < 2 else f"± {q_ci:.2g} (n = {n})"
    held = sum(holds(m) and ok for m, ok in zip(margins, acting, strict=True))
    ours = (
        f"{label} = {q_mean:.4g} {spread}{_two_values(claim, [s for s, _ in measured])}; "
        f"holds in {held} of {n} runs; rule: {decision.rule}"
    )
    if claim.requires:
        need = ", ".join(str(r) for r in claim.requires)
        ours += f"; requires {need}: met in {sum(acting)} of {n}"
    missing = len(every) - n
    if missing:
        ours = (
            f"{missing} of {len(every)} runs missing (failed, or no value); "
            f"the {n} measured: {verdict}: {ours}"
        )
        verdict = "not measured"
    return Verdict(claim, verdict, ours, q_mean, None if n < 2 else q_ci, n)

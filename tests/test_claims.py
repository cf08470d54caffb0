"""Claims as data (issue #8 part 1): the shipped claims file validates, names real
experiments, and the verdict logic judges synthetic summaries as documented."""

from __future__ import annotations

from pathlib import Path

import pytest

from ccm.claims import evaluate, load_claims, parse_claim
from ccm.cli import group_options
from ccm.errors import ConfigError

CLAIMS = Path(__file__).resolve().parents[1] / "experiments" / "claims.yaml"


def test_shipped_claims_validate_and_cover_both_papers() -> None:
    claims = load_claims(CLAIMS)
    experiments = set(group_options("experiment"))
    assert {c.experiment for c in claims} <= experiments
    ids = {c.id for c in claims}
    for prefix in ("H1", "H2", "H3", "H4", "Table1", "B-6.1", "B-6.2", "B-T3", "B-6.4", "B-5.3"):
        assert any(i.startswith(prefix) for i in ids), prefix


def _summary(exp: str, a: float, b: float, trials: list | None = None) -> dict:
    return {
        "experiment": exp,
        "status": "ok",
        "conditions": {"x": {"m": a}, "y": {"m": b}},
        "trials": trials or [],
    }


LESS = {
    "id": "c", "paper": "seed_b", "source": "Fig. 1", "statement": "x below y",
    "paper_value": "q", "experiment": "e", "compare": "less_than",
    "a": {"condition": "x", "metric": "m"}, "b": {"condition": "y", "metric": "m"},
}  # fmt: skip


@pytest.mark.parametrize(
    ("pairs", "verdict"),
    [
        ([(1.0, 2.0), (1.1, 2.0), (0.9, 2.1)], "reproduced"),
        ([(1.0, 2.0), (3.0, 2.0), (0.5, 2.0)], "partially"),  # mean below, CI crosses 0
        ([(3.0, 2.0), (2.5, 2.0), (2.9, 2.1)], "not reproduced"),
    ],
)
def test_less_than_verdicts(pairs: list, verdict: str) -> None:
    c = parse_claim(LESS, "claims[0]")
    v = evaluate(c, [_summary("e", a, b) for a, b in pairs])
    assert v.verdict == verdict and v.n_seeds == 3


def test_one_seed_has_no_interval() -> None:
    v = evaluate(parse_claim(LESS, "claims[0]"), [_summary("e", 1.0, 2.0)])
    assert v.n_seeds == 1 and v.ci95 is None and "no interval" in v.ours and "±" not in v.ours


def test_bounds_hold_at_equality_and_missing_values_are_not_measured() -> None:
    c = parse_claim({**LESS, "compare": "at_least", "value": 1.0, "b": None}, "claims[0]")
    assert evaluate(c, [_summary("e", 1.0, 0.0)] * 3).verdict == "reproduced"
    assert evaluate(c, [_summary("other", 1.0, 0.0)]).verdict == "not measured"
    failed = {**_summary("e", 1.0, 0.0), "status": "failed"}
    assert evaluate(c, [failed]).verdict == "not measured"


def test_ratio_and_trial_references() -> None:
    trials = [{"condition": "x", "trial": 1, "t": 10.0}, {"condition": "x", "trial": 5, "t": 4.0}]
    c = parse_claim(
        {**LESS, "compare": "ratio_at_most", "value": 0.5,
         "a": {"condition": "x", "metric": "t", "trial": 5},
         "b": {"condition": "x", "metric": "t", "trial": 1}},
        "claims[0]",
    )  # fmt: skip
    v = evaluate(c, [_summary("e", 0.0, 0.0, trials)])
    assert v.verdict == "reproduced" and v.mean == pytest.approx(0.4)


def test_difference_and_within() -> None:
    """``difference_at_most``: a − b <= value; ``within``: |a − value| <= tolerance·|value|."""
    diff = parse_claim({**LESS, "compare": "difference_at_most", "value": 3.7}, "claims[0]")
    assert evaluate(diff, [_summary("e", 16.0, 13.0)] * 3).verdict == "reproduced"
    v = evaluate(diff, [_summary("e", 20.0, 13.0)] * 3)
    assert v.verdict == "not reproduced" and v.mean == pytest.approx(7.0)
    within = {**LESS, "compare": "within", "value": 8.0, "tolerance": 0.15, "b": None}
    c = parse_claim(within, "claims[0]")
    assert evaluate(c, [_summary("e", 9.2, 0.0)] * 3).verdict == "reproduced"  # at the edge
    assert evaluate(c, [_summary("e", 6.0, 0.0)] * 3).verdict == "not reproduced"
    assert evaluate(c, [_summary("e", 10.0, 0.0)] * 3).verdict == "not reproduced"


def test_a_claim_whose_mechanism_is_inert_does_not_reproduce() -> None:
    """``requires``: a run counts only if the mechanism acted in it (x.act within bounds)."""
    c = parse_claim(
        {**LESS, "requires": [{"condition": "x", "metric": "act", "at_least": 0.02}]}, "claims[0]"
    )

    def run(act: float | None) -> dict:
        s = _summary("e", 1.0, 2.0)
        s["conditions"]["x"]["act"] = act
        return s

    assert evaluate(c, [run(0.5)] * 3).verdict == "reproduced"
    inert = evaluate(c, [run(0.0)] * 3)
    assert inert.verdict == "not reproduced" and "met in 0 of 3" in inert.ours
    assert "holds in 0 of 3" in inert.ours
    assert evaluate(c, [run(0.5), run(0.5), run(None)]).verdict == "partially"


def test_a_task_claim_reads_only_that_tasks_runs() -> None:
    c = parse_claim({**LESS, "task": "porridge"}, "claims[0]")
    runs = [{**_summary("e", 1.0, 2.0), "task": "porridge"},
            {**_summary("e", 3.0, 2.0), "task": "springs"}]  # fmt: skip
    v = evaluate(c, runs)
    assert v.n_seeds == 1 and v.verdict == "reproduced"


@pytest.mark.parametrize(
    ("change", "key"),
    [
        ({"requires": [{"condition": "x", "metric": "m"}]}, "claims[0].requires[0]"),
        ({"requires": [{"condition": "x", "metric": "m", "at_most": "a"}]}, "requires[0].at_most"),
        ({"compare": "bigger"}, "claims[0].compare"),
        ({"paper": "seed_c"}, "claims[0].paper"),
        ({"a": {"condition": "x"}}, "claims[0].a.metric"),
        ({"a": {"condition": "x", "metric": "m", "trial": 0}}, "claims[0].a.trial"),
        ({"compare": "at_most"}, "claims[0].value"),
        ({"compare": "within", "value": 8.0}, "claims[0].tolerance"),
        ({"compare": "at_most", "value": 8.0, "tolerance": 0.1}, "claims[0].tolerance"),
        ({"colour": "red"}, "claims[0].colour"),
        ({"statement": ""}, "claims[0].statement"),
    ],
)
def test_bad_claims_name_the_key(change: dict, key: str) -> None:
    with pytest.raises(ConfigError) as err:
        parse_claim({**LESS, **change}, "claims[0]")
    assert key in str(err.value)


def test_duplicate_ids_and_unreadable_files(tmp_path: Path) -> None:
    import yaml

    path = tmp_path / "claims.yaml"
    path.write_text(yaml.safe_dump({"claims": [LESS, LESS]}), encoding="utf-8")
    with pytest.raises(ConfigError, match="duplicate id"):
        load_claims(path)
    path.write_text("claims: [\n", encoding="utf-8")
    with pytest.raises(ConfigError, match="cannot read claims"):
        load_claims(path)

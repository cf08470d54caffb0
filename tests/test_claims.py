"""Claims as data (issue #8 part 1): the shipped claims file validates, names real
experiments, and the verdict logic judges synthetic summaries as documented."""

from __future__ import annotations

import math
import re
from pathlib import Path

import pytest
from omegaconf import OmegaConf

from ccm.cli import config_dir, group_options
from ccm.core.errors import ConfigError
from ccm.reporting.claims import evaluate, load_claims, parse_claim

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


def test_ratio_within() -> None:
    """``ratio_within``: |a / b − value| <= tolerance·|value| (e.g. proportional: 2 ± 25 %)."""
    c = parse_claim({**LESS, "compare": "ratio_within", "value": 2.0, "tolerance": 0.25}, "c")
    assert evaluate(c, [_summary("e", 5.0, 2.0)] * 3).verdict == "reproduced"  # 2.5: at the edge
    assert evaluate(c, [_summary("e", 2.9, 2.0)] * 3).verdict == "not reproduced"  # 1.45: below
    assert evaluate(c, [_summary("e", 6.0, 2.0)] * 3).verdict == "not reproduced"  # 3.0: above
    with pytest.raises(ConfigError, match="tolerance"):
        parse_claim({**LESS, "compare": "ratio_within", "value": 2.0}, "c")


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


def test_a_signed_error_is_bounded_by_its_size() -> None:
    """``abs: true`` judges |error| against an upper bound: −10 mm is not within 1 mm."""
    claim = {**LESS, "compare": "at_most", "value": 0.001, "b": None,
             "a": {"condition": "x", "metric": "m", "abs": True}}  # fmt: skip
    c = parse_claim(claim, "claims[0]")
    assert evaluate(c, [_summary("e", -0.010, 0.0)] * 3).verdict == "not reproduced"
    assert evaluate(c, [_summary("e", -0.0005, 0.0)] * 3).verdict == "reproduced"
    signed = parse_claim({**claim, "a": {"condition": "x", "metric": "m"}}, "claims[0]")
    assert evaluate(signed, [_summary("e", -0.010, 0.0)] * 3).verdict == "reproduced"
    with pytest.raises(ConfigError, match=r"claims\[0\]\.a\.abs"):
        parse_claim({**claim, "a": {"condition": "x", "metric": "m", "abs": "yes"}}, "claims[0]")


def test_a_failed_seed_or_missing_value_makes_the_claim_not_measured() -> None:
    """One ok seed and four failed ones is no verdict (issue #18): the text says how many runs
    are missing and what the measured ones give."""
    c = parse_claim(LESS, "claims[0]")
    failed = {"experiment": "e", "status": "failed", "error": "boom"}
    v = evaluate(c, [_summary("e", 1.0, 2.0), *[failed] * 4])
    assert v.verdict == "not measured" and v.n_seeds == 1
    assert v.ours.startswith(
        "4 of 5 runs missing (failed, or no value); the 1 measured: reproduced"
    )
    no_value = {**_summary("e", 1.0, 2.0), "conditions": {"x": {"m": None}, "y": {"m": 2.0}}}
    assert evaluate(c, [_summary("e", 1.0, 2.0)] * 4 + [no_value]).verdict == "not measured"
    assert evaluate(c, [_summary("e", 1.0, 2.0)] * 5).verdict == "reproduced"


def test_a_bound_met_by_nothing_happening_needs_its_precondition() -> None:
    """H2-no-false-new-modes: zero false new modes in runs without a single transition is
    no evidence; the shipped claim requires n_true_transitions >= 1."""
    shipped = {c.id: c for c in load_claims(CLAIMS)}["H2-no-false-new-modes"]
    assert [str(r) for r in shipped.requires] == ["1 <= avic_modes.n_true_transitions"]

    def run(transitions: float) -> dict:
        m = {"false_new_modes": 0.0, "n_true_transitions": transitions}
        return {"experiment": shipped.experiment, "status": "ok", "conditions": {"avic_modes": m}}

    assert evaluate(shipped, [run(0.0)] * 3).verdict == "not reproduced"
    assert evaluate(shipped, [run(4.0)] * 3).verdict == "reproduced"


def test_the_rule_is_the_claims_never_the_margins_shape() -> None:
    """Issue #38: the rule is fixed in claims.yaml before the runs. Five seeds that all hold,
    one by far more: the t-interval (the default) crosses zero, so *partially*, whatever
    the margins' shape (until #38 Shapiro-Wilk switched such margins to a sign test). The
    sign test's tail: P(X >= 5 | n = 5) = 1/32, P(X >= 4 | n = 5) = 6/32, P(X >= 9 | n = 10)
    = 11/1024."""
    from ccm.reporting.claim_stats import decide, sign_test_p

    assert sign_test_p(5, 5) == pytest.approx(1 / 32) and sign_test_p(4, 5) == pytest.approx(6 / 32)
    assert sign_test_p(9, 10) == pytest.approx(11 / 1024) and sign_test_p(0, 5) == 1.0
    c = parse_claim(LESS, "claims[0]")
    assert c.test == "t"
    heavy = [(1.0, 1.01), (1.0, 1.02), (1.0, 1.01), (1.0, 1.02), (1.0, 9.0)]  # margins b − a
    v = evaluate(c, [_summary("e", a, b) for a, b in heavy])
    # mean 1.612, sd 3.571, t(4) = 2.776: the interval's lower end is 1.612 - 4.433 < 0
    assert v.verdict == "partially" and "95 % t-interval" in v.ours and "sign" not in v.ours
    normal = decide([0.9, 1.1, 1.0, 1.2, 0.8], lambda m: m > 0)
    assert normal.verdict == "reproduced" and normal.rule == "95 % t-interval of the mean margin"
    with pytest.raises(ValueError, match="test must be one of"):
        decide([0.9, 1.1], lambda m: m > 0, "auto")


def test_a_sign_test_on_fewer_runs_than_it_was_fixed_for_is_at_most_partial() -> None:
    """5 of 5 holding gives p = 1/32 < 0.05, but the rule is fixed for 10 runs: a quick run
    (or a five-seed sweep) cannot reproduce under it."""
    from ccm.reporting.claim_stats import decide

    d = decide([0.1, 0.2, 0.3, 0.4, 0.5], lambda m: m > 0, "sign")
    assert d.verdict == "partially" and "5 of 5 hold, p = 0.0312" in d.rule
    assert "fewer than the 10 runs" in d.rule
    assert decide([0.1, -0.2, -0.3, -0.4, 0.5], lambda m: m > 0, "sign").verdict == "not reproduced"


def test_every_sign_test_claim_has_ten_seeds() -> None:
    """A shipped ``test: sign`` claim's experiment sweeps at least the 10 seeds the rule is
    fixed for (issue #38: "use 10 seeds where a sign test decides")."""
    from ccm.reporting.claim_stats import SIGN_TEST_RUNS

    short = []
    for c in load_claims(CLAIMS):
        if c.test != "sign":
            continue
        cfg = OmegaConf.load(config_dir() / "experiment" / f"{c.experiment}.yaml")
        seeds = str(OmegaConf.select(cfg, "hydra.sweeper.params.seed")).split(",")
        if len(seeds) < SIGN_TEST_RUNS:
            short.append((c.id, c.experiment, len(seeds)))
    assert short == []
    assert sum(c.test == "sign" for c in load_claims(CLAIMS)) >= 10


def test_run_info_reference_reads_the_wall_clock_facts(tmp_path: Path) -> None:
    """``condition: run_info`` reads a scalar of run_info.json, joined by ccm report's
    collect; without the file the claim is not measured."""
    import json

    from ccm.reporting.report_runs import collect

    c = parse_claim(
        {**LESS, "compare": "within", "value": 3300.0, "tolerance": 0.5, "b": None,
         "a": {"condition": "run_info", "metric": "train_s"}}, "c",
    )  # fmt: skip
    for seed, train in ((0, 2000.0), (1, 2100.0), (2, 1900.0)):
        run = tmp_path / f"s{seed}"
        run.mkdir()
        (run / "summary.json").write_text(json.dumps(_summary("e", 0.0, 0.0)))
        (run / "run_info.json").write_text(json.dumps({"train_s": train, "per": {"x": 1.0}}))
    runs = [s for _, s in collect(tmp_path)]
    assert evaluate(c, runs).verdict == "reproduced"  # 1900-2100 s within 3300 +- 50 %
    fast = parse_claim(
        {
            **LESS,
            "compare": "within",
            "value": 30000.0,
            "tolerance": 0.5,
            "b": None,
            "a": {"condition": "run_info", "metric": "train_s"},
        },
        "c",
    )
    assert evaluate(fast, runs).verdict == "not reproduced"
    assert evaluate(c, [_summary("e", 0.0, 0.0)] * 3).verdict == "not measured"


def test_every_claim_is_in_the_claim_map() -> None:
    """experiments/README.md maps each paper part to its claim ids (issue #18): none left out."""
    root = Path(__file__).resolve().parents[1]
    text = (root / "experiments" / "README.md").read_text(encoding="utf-8")
    listed = set(re.findall(r"[\w.-]+", text[text.index("## Claim map") :]))
    missing = [
        c.id for c in load_claims(root / "experiments" / "claims.yaml") if c.id not in listed
    ]
    assert missing == []


def test_a_claim_can_fix_the_sign_test_as_its_rule() -> None:
    """``test: sign`` (issue #38): the sign test decides even for normal margins; at n = 10,
    9 holding runs reproduce (p = 0.011) and 8 do not (p = 0.055: partially)."""
    c = parse_claim({**LESS, "test": "sign"}, "claims[0]")
    nine = [(1.0, 2.0 + 0.01 * i) for i in range(9)] + [(2.5, 2.0)]
    v = evaluate(c, [_summary("e", a, b) for a, b in nine])
    assert v.verdict == "reproduced" and "sign test (9 of 10 hold, p = 0.0107; the claim" in v.ours
    # margins b − a at the normal quantiles of 0.5 ± 0.5: 8 of 10 hold
    margins = [-0.322, -0.018, 0.163, 0.307, 0.437, 0.563, 0.693, 0.837, 1.018, 1.322]
    eight = [_summary("e", 1.0, 1.0 + m) for m in margins]
    assert evaluate(c, eight).verdict == "partially"
    t_rule = evaluate(parse_claim(LESS, "claims[0]"), eight)  # the default: the t-interval
    assert t_rule.verdict == "reproduced" and "95 % t-interval" in t_rule.ours
    with pytest.raises(ConfigError, match=r"claims\[0\]\.test"):
        parse_claim({**LESS, "test": "wilcoxon"}, "claims[0]")


def test_identical_runs_are_one_run_not_a_sample() -> None:
    """Ten seeds of a deterministic protocol (seed A §4.1's noiseless world) give the same
    margin: the verdict is that one run's, and the report says so instead of a p-value."""
    for test in ("t", "sign"):
        c = parse_claim({**LESS, "test": test}, "claims[0]")
        v = evaluate(c, [_summary("e", 1.0, 2.0)] * 10)
        assert v.verdict == "reproduced" and "10 runs are identical (deterministic)" in v.ours
        assert "p =" not in v.ours
        v = evaluate(c, [_summary("e", 3.0, 2.0)] * 10)
        assert v.verdict == "not reproduced"


def test_diagnostic_claims_are_flagged() -> None:
    """``diagnostic: true`` marks a robustness row (shown, not tallied: test_report); the
    shipped H1 forward-model claims are judged on seed A §4.1's protocol, with their noisy
    50 ms twins as diagnostic rows (issue #38)."""
    assert parse_claim({**LESS, "diagnostic": True}, "c").diagnostic
    assert not parse_claim(LESS, "c").diagnostic
    with pytest.raises(ConfigError, match=r"claims\[0\]\.diagnostic"):
        parse_claim({**LESS, "diagnostic": "yes"}, "claims[0]")
    shipped = {c.id: c for c in load_claims(CLAIMS)}
    for cid in ("H1-forward-model", "H1-incremental-beats-persistence", "H1-fixed-gmm-guided-avic"):
        paper, robust = shipped[cid], shipped[f"{cid}-noisy-50ms"]
        assert paper.experiment == "h1_forward_model_one_step" and not paper.diagnostic
        assert robust.experiment == "h1_forward_model" and robust.diagnostic
        assert paper.test == robust.test == "sign"
        assert (paper.compare, paper.a, paper.b, paper.value, paper.requires) == (
            robust.compare, robust.a, robust.b, robust.value, robust.requires
        )  # fmt: skip


_AT_MOST = {**LESS, "compare": "at_most", "value": 1.0}
_WITHIN = {**LESS, "compare": "within", "value": 1.0, "tolerance": 0.1}


@pytest.mark.parametrize(
    ("claim", "line"),
    [
        ("x", "c0: must be a mapping"),
        ({**LESS, "source": ""}, "c0.source: is required"),
        ({**LESS, "statement": None}, "c0.statement: is required"),
        ({**LESS, "paper": "seed_c"}, "c0.paper: must be seed_a or seed_b, got 'seed_c'"),
        ({**LESS, "compare": "below"}, "c0.compare: must be one of less_than, "),
        ({**LESS, "a": "x.m"}, "c0.a: must be a mapping {condition, metric[, trial]}"),
        ({**LESS, "b": None}, "c0.b: must be a mapping {condition, metric[, trial]}"),
        ({**LESS, "a": {"condition": "x", "metric": "m", "trial": 0}},
         "c0.a.trial: must be a trial number >= 1, got 0"),
        ({**LESS, "a": {"condition": "x", "metric": "m", "trial": True}},
         "c0.a.trial: must be a trial number >= 1, got True"),
        ({**LESS, "a": {"condition": "", "metric": "m"}},
         "c0.a.condition: is required (a non-empty string)"),
        ({**LESS, "b": {"condition": "y", "metric": 3}},
         "c0.b.metric: is required (a non-empty string)"),
        ({**LESS, "a": {"condition": "x", "metric": "m", "abs": "yes"}},
         "c0.a.abs: must be true or false, got 'yes'"),
        ({**LESS, "a": {"condition": "x", "metric": "m", "mean": 1}}, "c0.a.mean: unknown key"),
        ({**LESS, "requires": [{"condition": "x", "metric": "m", "at_most": 1, "below": 2}]},
         "c0.requires[0].below: unknown key"),
        ({**LESS, "requires": [{"condition": "", "metric": "m", "at_most": 1}]},
         "c0.requires[0].condition: is required"),
        ({**_AT_MOST, "value": math.nan}, "c0.value: a finite number is required for at_most"),
        ({**_WITHIN, "tolerance": 0}, "c0.tolerance: a fraction > 0 is required for within, got 0"),
        ({**_WITHIN, "tolerance": math.inf}, "c0.tolerance: a fraction > 0 is required for within"),
        ({**LESS, "tolerance": 0.1}, "c0.tolerance: is only used with compare: within or "
                                     "ratio_within, not less_than"),
        ({**LESS, "figures": "a.png"}, "c0.figures: must be a list of figure file names"),
        ({**LESS, "figures": ["a.png", 3]}, "c0.figures: must be a list of figure file names"),
        ({**LESS, "requires": {"condition": "x"}}, "c0.requires: must be a list of {condition, "
                                                   "metric, bounds}"),
        ({**LESS, "requires": ["x"]}, "c0.requires[0]: must be a mapping {condition, metric, "
                                      "at_least and/or at_most}"),
        ({**LESS, "requires": [{"condition": "x", "metric": "m"}]},
         "c0.requires[0]: needs at_least and/or at_most"),
        ({**LESS, "requires": [{"condition": "x", "metric": "m", "at_most": "1"}]},
         "c0.requires[0].at_most: must be a finite number, got '1'"),
        ({**LESS, "requires": [{"condition": "x", "metric": "m", "at_most": 1,
                                "changed_from": "y"}]},
         "c0.requires[0].changed_from: must be a mapping"),
        ({**LESS, "test": "auto"}, "c0.test: must be one of t, sign, got 'auto'"),
        ({**LESS, "diagnostic": 1}, "c0.diagnostic: must be true or false, got 1"),
    ],
)  # fmt: skip
def test_a_bad_claim_gets_one_line_naming_its_key(claim: object, line: str) -> None:
    """Every parse error is one line that names the claim's key and what is allowed."""
    with pytest.raises(ConfigError) as err:
        parse_claim(claim, "c0")
    assert str(err.value).startswith(line) and "\n" not in str(err.value)


def test_the_claims_file_errors_name_the_file_or_the_claim(tmp_path: Path) -> None:
    """An unreadable file, a file without a claims list and a duplicate id each get one line
    naming where; the parsed optional fields keep their values."""
    missing = tmp_path / "none.yaml"
    with pytest.raises(
        ConfigError, match=rf"^{re.escape(str(missing))}: cannot read claims: \[Errno 2\] No such"
    ):
        load_claims(missing)
    empty = tmp_path / "empty.yaml"
    for text in ("claims: []\n", "- a\n- b\n"):
        empty.write_text(text, encoding="utf-8")
        with pytest.raises(ConfigError, match=rf"^{re.escape(str(empty))}:claims: must be a non"):
            load_claims(empty)
    bad = tmp_path / "bad.yaml"
    bad.write_text("claims: [\n", encoding="utf-8")
    with pytest.raises(ConfigError, match=rf"^{re.escape(str(bad))}: cannot read claims: \S"):
        load_claims(bad)
    import yaml

    two = tmp_path / "two.yaml"
    one = {**LESS, "note": "n", "discussion": "experiments/x.md", "figures": ["f.png"]}
    two.write_text(yaml.safe_dump({"claims": [one, one]}), encoding="utf-8")
    with pytest.raises(ConfigError, match=r"^claims\[1\]\.id: duplicate id 'c'$"):
        load_claims(two)
    two.write_text(yaml.safe_dump({"claims": [one, {**one, "paper": "x"}]}), encoding="utf-8")
    with pytest.raises(ConfigError, match=r"^claims\[1\]\.paper: must be seed_a or seed_b"):
        load_claims(two)
    c = parse_claim(one, "c0")
    assert (c.note, c.discussion, c.figures, c.source, c.statement, c.paper_value) == (
        "n", "experiments/x.md", ("f.png",), "Fig. 1", "x below y", "q"
    )  # fmt: skip
    assert (c.paper, c.task, c.test, c.diagnostic) == ("seed_b", None, "t", False)

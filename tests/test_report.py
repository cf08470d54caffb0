"""``ccm report DIR`` (issue #8 part 3): claims with verdicts and embedded figures, metric
tables over seeds, and run failures with their causes."""

from __future__ import annotations

import json
from html.parser import HTMLParser
from pathlib import Path

import pytest

from ccm.core.errors import ConfigError
from ccm.reporting.report import main, metrics_table

PNG = bytes.fromhex(
    "89504e470d0a1a0a0000000d4948445200000001000000010806000000"
    "1f15c4890000000d49444154789c6360000002000154a24f5d0000000049454e44ae426082"
)
CLAIMS = """claims:
  - {id: c1, paper: seed_b, source: "Fig. 6", statement: "x below y", paper_value: "q",
     experiment: e, compare: less_than, a: {condition: x, metric: m},
     b: {condition: y, metric: m}, figures: [f.png]}
  - {id: c2, paper: seed_a, source: "Fig. 1", statement: "unmeasured", paper_value: "q",
     experiment: other, compare: at_most, a: {condition: x, metric: m}, value: 1.0}
"""


def _run(root: Path, name: str, summary: dict, figure: bool = False) -> None:
    d = root / name
    (d / "figures").mkdir(parents=True)
    (d / "summary.json").write_text(json.dumps(summary), encoding="utf-8")
    if figure:
        (d / "figures" / "f.png").write_bytes(PNG)


@pytest.fixture
def sweep(tmp_path: Path) -> Path:
    root = tmp_path / "multirun"
    for seed, (a, b) in enumerate([(1.0, 2.0), (1.2, 2.1), (0.9, 2.0)]):
        _run(root, str(seed), {"experiment": "e", "status": "ok", "seed": seed,
                               "conditions": {"x": {"m": a}, "y": {"m": b}}, "trials": []},
             figure=seed == 0)  # fmt: skip
    _run(root, "3", {"experiment": "e", "status": "failed", "error": "controller.k: must be > 0"})
    (tmp_path / "claims.yaml").write_text(CLAIMS, encoding="utf-8")
    return root


def test_report_lists_claims_verdicts_figures_and_failures(sweep: Path) -> None:
    assert main([str(sweep), "--claims", str(sweep.parent / "claims.yaml")]) == 0
    md = (sweep / "report.md").read_text(encoding="utf-8")
    page = (sweep / "report.html").read_text(encoding="utf-8")
    # one of c1's four runs failed: not measured, with what the three measured ones give
    assert "**c1**" in md and "**reproduced**" not in md and "**not measured**" in md
    assert "1 of 4 runs missing (failed, or no value); the 3 measured: reproduced" in md
    assert "controller.k: must be > 0" in md and "controller.k: must be &gt; 0" not in md
    assert "data:image/png;base64," in page  # self-contained: the figure is embedded
    assert "controller.k: must be &gt; 0" in page
    assert "src='http" not in page and "<script" not in page

    class Tags(HTMLParser):
        def __init__(self) -> None:
            super().__init__()
            self.stack: list[str] = []
            self.ok = True

        def handle_starttag(self, tag: str, attrs: list) -> None:
            if tag not in ("meta", "img", "br"):
                self.stack.append(tag)

        def handle_endtag(self, tag: str) -> None:
            self.ok &= bool(self.stack) and self.stack.pop() == tag

    parser = Tags()
    parser.feed(page)
    assert parser.ok and parser.stack == []  # every element closed, in order


def test_a_claim_needs_every_run_of_its_experiment(sweep: Path) -> None:
    """Without the failed run the three seeds decide; a run dir that never wrote its
    summary (a killed job: only its Hydra config) counts as missing again."""
    import shutil

    shutil.rmtree(sweep / "3")
    claims = str(sweep.parent / "claims.yaml")
    assert main([str(sweep), "--claims", claims]) == 0
    md = (sweep / "report.md").read_text(encoding="utf-8")
    assert "**reproduced**" in md and "runs missing" not in md
    assert "x.m = 1.033, y.m = 2.033" in md  # the values behind the comparison
    hydra = sweep / "4" / ".hydra"
    hydra.mkdir(parents=True)
    (hydra / "config.yaml").write_text("experiment:\n  name: e\nseed: 4\n", encoding="utf-8")
    assert main([str(sweep), "--claims", claims]) == 0
    md = (sweep / "report.md").read_text(encoding="utf-8")
    assert "1 of 4 runs missing" in md and "no summary.json" in md


def test_a_report_of_truncated_runs_says_it_is_no_result(sweep: Path) -> None:
    """Runs cut short (experiment.fast, as make reproduce-paper-quick) put a banner on top
    when they are all there is; beside full runs they are set aside, not pooled (issue #19)."""
    claims = str(sweep.parent / "claims.yaml")
    assert main([str(sweep), "--claims", claims]) == 0
    assert "Not results" not in (sweep / "report.md").read_text(encoding="utf-8")
    for run in ("0", "1", "2", "3"):
        hydra = sweep / run / ".hydra"
        hydra.mkdir()
        (hydra / "config.yaml").write_text("experiment:\n  name: e\n  fast: true\n", "utf-8")
    assert main([str(sweep), "--claims", claims]) == 0
    md = (sweep / "report.md").read_text(encoding="utf-8")
    page = (sweep / "report.html").read_text(encoding="utf-8")
    assert md.splitlines()[2].startswith("**Not results: 4 of 4 runs were truncated**")
    assert "class='banner'>Not results: 4 of 4 runs were truncated" in page


def test_truncated_runs_beside_full_ones_are_set_aside(sweep: Path) -> None:
    hydra = sweep / "0" / ".hydra"
    hydra.mkdir()
    (hydra / "config.yaml").write_text("experiment:\n  name: e\n  fast: true\n", "utf-8")
    assert main([str(sweep), "--claims", str(sweep.parent / "claims.yaml")]) == 0
    md = (sweep / "report.md").read_text(encoding="utf-8")
    assert "Not results" not in md
    assert md.splitlines()[2].startswith("4 runs, 2 usable (1 failed, 1 set aside (mixed-mode))")
    assert "set aside (mixed-mode): a truncated run beside full runs" in md
    assert "x.m = 1.05, y.m = 2.05" in md  # seeds 1 and 2 only


def test_the_same_seed_twice_counts_once(sweep: Path) -> None:
    """A copy of seed 1's run (another sweep directory) is a duplicate, not a fourth seed."""
    import shutil

    shutil.copytree(sweep / "1", sweep / "zz_rerun_1")
    assert main([str(sweep), "--claims", str(sweep.parent / "claims.yaml")]) == 0
    md = (sweep / "report.md").read_text(encoding="utf-8")
    assert "set aside (duplicate): the same experiment, seed and task as" in md
    assert "x.m = 1.033, y.m = 2.033" in md  # the three seeds, as without the copy
    assert "(n = 3)" in md


def test_records_moved_aside_by_force_are_not_pooled(sweep: Path) -> None:
    import shutil

    shutil.copytree(sweep / "3", sweep / "0.replaced-20261203-080000")
    (sweep / "0.replaced-20261203-080000" / "summary.json").write_text(json.dumps(
        {"experiment": "e", "status": "ok", "seed": 7, "trials": [],
         "conditions": {"x": {"m": 9.0}, "y": {"m": 0.0}}}), encoding="utf-8")  # fmt: skip
    assert main([str(sweep), "--claims", str(sweep.parent / "claims.yaml")]) == 0
    md = (sweep / "report.md").read_text(encoding="utf-8")
    assert "set aside (replaced): a record moved aside by ccm run --force" in md
    assert "x.m = 1.033, y.m = 2.033" in md


def test_missing_metric_values_are_counted_not_hidden(sweep: Path) -> None:
    from ccm.reporting.report_runs import collect

    (sweep / "2" / "summary.json").write_text(json.dumps(
        {"experiment": "e", "status": "ok", "seed": 2, "trials": [],
         "conditions": {"x": {"m": None}, "y": {"m": 2.0}}}), encoding="utf-8")  # fmt: skip
    t = metrics_table(collect(sweep))
    row = t[(t.condition == "x") & (t.metric == "m")].iloc[0]
    assert row["n"] == 2 and row["missing"] == 1
    assert main([str(sweep), "--claims", str(sweep.parent / "claims.yaml")]) == 0
    assert "| x | m | 1.1 | " in (sweep / "report.md").read_text(encoding="utf-8")


def test_a_report_with_no_usable_run_exits_non_zero(
    sweep: Path, capsys: pytest.CaptureFixture
) -> None:
    for seed in ("0", "1", "2"):
        (sweep / seed / "summary.json").write_text(json.dumps(
            {"experiment": "e", "status": "interrupted", "seed": int(seed),
             "error": "interrupted by SIGINT"}), encoding="utf-8")  # fmt: skip
    assert main([str(sweep), "--claims", str(sweep.parent / "claims.yaml")]) == 1
    err = capsys.readouterr().err.strip().splitlines()
    assert err == [f"ccm: error: report.dir: no usable run under {sweep} (4 runs, 0 usable "
                   "(1 failed, 3 interrupted)); the report lists why"]  # fmt: skip
    md = (sweep / "report.md").read_text(encoding="utf-8")
    assert "interrupted: interrupted by SIGINT" in md


def test_metrics_table_means_over_seeds(sweep: Path) -> None:
    from ccm.reporting.report_runs import collect

    t = metrics_table(collect(sweep))
    row = t[(t.condition == "x") & (t.metric == "m")].iloc[0]
    assert row["mean"] == pytest.approx(31 / 30) and row["n"] == 3


def test_report_help(capsys: pytest.CaptureFixture) -> None:
    assert main(["--help"]) == 0
    assert capsys.readouterr().out.startswith("usage: ccm report DIR")


def test_bad_report_input(tmp_path: Path) -> None:
    with pytest.raises(ConfigError, match="no summary.json"):
        main([str(tmp_path)])
    with pytest.raises(ConfigError, match="not a directory"):
        main([str(tmp_path / "missing")])
    with pytest.raises(ConfigError, match="usage"):
        main([])


def test_cli_report_command(sweep: Path, tmp_path: Path, capsys: pytest.CaptureFixture) -> None:
    from ccm.cli import main as ccm_main

    claims = str(sweep.parent / "claims.yaml")
    assert ccm_main(["report", str(sweep), "--claims", claims]) == 0
    assert (sweep / "report.html").is_file()
    assert ccm_main(["report", str(tmp_path / "missing")]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and err[0].startswith("ccm: error: report.dir")


def test_diagnostic_claims_are_shown_but_not_tallied(sweep: Path) -> None:
    """``diagnostic: true`` (issue #38: a robustness row beside the paper's protocol): the
    row and its verdict are in the report, marked, and the tally counts only the others."""
    import shutil

    shutil.rmtree(sweep / "3")  # the failed run: c1 gets a verdict
    diag = """  - {id: c3, paper: seed_b, source: "Fig. 6", statement: "x below y, noisy",
     paper_value: "q", experiment: e, compare: less_than, a: {condition: x, metric: m},
     b: {condition: y, metric: m}, diagnostic: true}
"""
    claims = sweep.parent / "claims.yaml"
    claims.write_text(claims.read_text(encoding="utf-8") + diag, encoding="utf-8")
    assert main([str(sweep), "--claims", str(claims)]) == 0
    md = (sweep / "report.md").read_text(encoding="utf-8")
    page = (sweep / "report.html").read_text(encoding="utf-8")
    assert "claims: 2 in claims.yaml: 1 not measured, 1 reproduced" in md
    assert "(and 1 diagnostic, not tallied: 1 reproduced)" in md
    assert "**c3**" in md and "**reproduced** (diagnostic, not tallied)" in md
    assert "<b>reproduced</b> (diagnostic, not tallied)" in page

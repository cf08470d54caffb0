"""``ccm report DIR``: aggregate the runs under DIR into report.md and report.html (issue #8).

DIR is one run directory or a multirun tree: every ``summary.json`` below it is read
(:mod:`ccm.reporting.report_runs`). The run's timing facts (``run_info.json``:
``mpc_rate_hz``, ``mpc_cpu_rate_hz``, ``mpc_iterations_median``, ``mpc_ms_per_iteration`` per
condition) join its conditions as metrics of the same names, so a claim can compare rates
measured in one process (seed B Table 2); summary.json itself stays free of them (it must be
identical run to run).

* **Claims** (``experiments/claims.yaml``, :mod:`ccm.reporting.claims`): for each claim whose
experiment
  has runs under DIR, the paper's value, ours (mean ± 95 % CI over the seeds found) and the
  verdict, with the claim's figures from the run of the lowest seed next to it. Claims whose
  experiment has no run under DIR are listed as not measured. Diagnostic claims (robustness
  rows, ``diagnostic: true``) are shown, marked, and left out of the tally.
* **Metrics**: per experiment and condition, the mean ± 95 % CI over seeds of every numeric
  metric (pandas), in a collapsible table.
* **Failures**: every run whose summary says ``failed``, with its cause.
* **Animations**: the clips in the runs' ``animations/`` (:mod:`ccm.reporting.report_media`).

The HTML is self-contained: figures are embedded as base64 PNG, no scripts, no external
files. Both files are written atomically (temp file + rename).
"""

from __future__ import annotations

import base64
import html
import math
import sys
from collections.abc import Sequence
from pathlib import Path
from typing import Any

from ccm.core.errors import ConfigError
from ccm.core.records import write_atomic
from ccm.core.stats import t95
from ccm.experiment.config_check import check_output_dir
from ccm.reporting.claims import Verdict, evaluate, load_claims
from ccm.reporting.report_media import animations_section
from ccm.reporting.report_runs import by_seed, truncated, usable_runs
from ccm.reporting.report_screen import SetAside, tally

DEFAULT_CLAIMS = Path(__file__).resolve().parents[2] / "experiments" / "claims.yaml"


def metrics_table(runs: Sequence[tuple[Path, dict[str, Any]]]) -> Any:
    """pandas DataFrame: experiment, condition, metric, mean, ci95, n, missing (ok runs
    only; ``missing``: runs whose value is None, a string or not finite, which the mean leaves
    out)."""
    import pandas as pd

    # a string where a number belongs is kept, as missing (issue #39: it was dropped unlisted)
    rows = [
        {"experiment": s.get("experiment"), "seed": s.get("seed"), "condition": cond,
         "metric": k, "value": _number(v)}
        for _, s in runs if s.get("status") == "ok"
        for cond, ms in (s.get("conditions") or {}).items()
        for k, v in ms.items()
        if v is None or isinstance(v, str | int | float) and not isinstance(v, bool)
    ]  # fmt: skip
    cols = ["experiment", "condition", "metric", "mean", "ci95", "n", "missing"]
    if not rows:
        return pd.DataFrame(columns=cols)
    df = pd.DataFrame(rows)
    g = df.groupby(["experiment", "condition", "metric"], sort=True)["value"]
    out = g.agg(["mean", "std", "count", "size"]).reset_index()
    out["missing"] = out.pop("size") - out["count"]
    # the claims' interval (Student t over seeds); one seed: NaN, shown as "–"
    out["ci95"] = out["count"].map(t95) * out["std"] / out["count"].clip(lower=1) ** 0.5
    return out.rename(columns={"count": "n"}).drop(columns="std")


def _number(v: float | str | None) -> float:
    """A metric value as a float; None, a string and non-finite values as NaN (counted as
    missing)."""
    return float(v) if isinstance(v, int | float) and math.isfinite(v) else math.nan


def _discussed(doc: str) -> str:
    return f"<br>discussed in <code>{html.escape(doc)}</code>" if doc else ""


def _mean(x: float) -> str:
    return "– (no value)" if math.isnan(x) else f"{x:.4g}"


def _ci(x: float) -> str:
    return "–" if math.isnan(x) else f"{x:.2g}"


def _figure(runs: Sequence[tuple[Path, dict]], experiment: str, name: str) -> Path | None:
    for d in by_seed(runs, experiment):
        if (d / "figures" / name).is_file():
            return d / "figures" / name
    return None


def _verdicts(runs: Sequence[tuple[Path, dict]], claims_path: Path) -> list[Verdict]:
    summaries = [s for _, s in runs]
    return [evaluate(c, summaries) for c in load_claims(claims_path)]


_STYLE = (
    "body{font-family:sans-serif;max-width:1400px;margin:2em auto;padding:0 1em}"
    "table{border-collapse:collapse;font-size:90%}table.claims{width:100%;table-layout:fixed}"
    "td,th{border:1px solid #ccc;padding:4px;vertical-align:top;overflow-wrap:anywhere}"
    "th.claim{width:18%}th.src{width:11%}th.paper{width:11%}th.ours{width:15%}"
    "th.verdict{width:8%}"
    ".reproduced{background:#d8f5d0}.partially{background:#fff2c2}"
    ".not.reproduced,.not-reproduced{background:#f8d0d0}.not-measured{background:#eee}"
    ".banner{background:#f8d0d0;border:2px solid #b00;padding:8px;font-weight:bold}"
    "img,video{max-width:100%;height:auto;display:block;margin:4px 0}"
)

Section = tuple[list[str], list[str]]  # (markdown lines, html lines)


def render(
    root: Path,
    claims_path: Path = DEFAULT_CLAIMS,
    screened: tuple[list[tuple[Path, dict[str, Any]]], list[SetAside]] | None = None,
) -> tuple[str, str]:
    """(markdown, html) of the report for the runs under ``root`` (``screened``: the result
    of :func:`usable_runs`, when the caller already has it)."""
    runs, aside = screened if screened is not None else usable_runs(root)
    verdicts = _verdicts(runs, claims_path)
    failures = [(d, f"{s.get('status', '?')}: {s.get('error', '?')}")
                for d, s in runs if s.get("status") != "ok"]  # fmt: skip
    failures += [(a.run, f"set aside ({a.kind}): {a.reason}") for a in aside]
    tally_claims = claim_tally(verdicts, claims_path.name)
    md, hb = _header(root, runs, f"{tally(runs, aside)}; claims: {tally_claims}.")
    for part in (
        _claim_rows(verdicts, runs, root),
        _not_pooled(failures),
        animations_section(root, runs),  # clips, where the runs have them
        _metrics_section(metrics_table(runs)),
    ):
        md += part[0]
        hb += part[1]
    hb.append("</body></html>")
    return "\n".join(md) + "\n", "\n".join(hb) + "\n"


def claim_tally(verdicts: Sequence[Verdict], name: str) -> str:
    """'N in <name>: k reproduced, ...' over the tallied claims, then the diagnostic rows
    (shown, not counted) with their own verdicts."""

    def counts(vs: Sequence[Verdict]) -> str:
        c: dict[str, int] = {}
        for v in vs:
            c[v.verdict] = c.get(v.verdict, 0) + 1
        return ", ".join(f"{n} {k}" for k, n in sorted(c.items()))

    tallied = [v for v in verdicts if not v.claim.diagnostic]
    diagnostic = [v for v in verdicts if v.claim.diagnostic]
    text = f"{len(tallied)} in {name}: {counts(tallied)}"
    if diagnostic:
        text += f" (and {len(diagnostic)} diagnostic, not tallied: {counts(diagnostic)})"
    return text


def _header(root: Path, runs: Sequence[tuple[Path, dict[str, Any]]], line: str) -> Section:
    """The title, a banner when any run was truncated, the tally and the claims table head."""
    cut = sum(truncated(d) for d, _ in runs)
    banner = (
        f"**Not results: {cut} of {len(runs)} runs were truncated** (`experiment.fast` or "
        "`max_time_s`, e.g. `make reproduce-paper-quick`). This report checks that the "
        "pipeline runs; its verdicts say nothing about the papers."
        if cut
        else ""
    )
    md = [
        f"# ccm report: {root}", "", *([banner, ""] if banner else []), line, "",
        "| claim | source | paper | ours (mean ± 95 % CI) | verdict |", "|---|---|---|---|---|",
    ]  # fmt: skip
    shown = html.escape(banner.replace("**", "").replace("`", ""))
    hb = [
        "<!doctype html><html><head><meta charset='utf-8'><title>ccm report</title><style>",
        _STYLE,
        "</style></head><body>",
        "<h1>ccm report</h1>"
        + (f"<p class='banner'>{shown}</p>" if banner else "")
        + f"<p>{html.escape(str(root))}: {html.escape(line.removesuffix('.'))}.</p>"
        "<h2>Claims</h2><table class='claims'><tr>"
        "<th class='claim'>claim</th><th class='src'>source</th><th class='paper'>paper</th>"
        "<th class='ours'>ours (mean ± 95 % CI)</th><th class='verdict'>verdict</th>"
        "<th>figures</th></tr>",
    ]
    return md, hb


def _claim_rows(
    verdicts: Sequence[Verdict], runs: Sequence[tuple[Path, dict[str, Any]]], root: Path
) -> Section:
    """One row per claim: statement, source, the paper's value, ours, verdict, figures."""
    md: list[str] = []
    hb: list[str] = []
    for v in verdicts:
        c = v.claim
        figs = [(f, _figure(runs, c.experiment, f)) for f in c.figures]
        md_figs = " ".join(f"[{f}]({p.relative_to(root)})" for f, p in figs if p is not None)
        note = f" ({c.note})" if c.note else ""
        doc = f"; discussed in `{c.discussion}`" if c.discussion else ""
        diag = " (diagnostic, not tallied)" if c.diagnostic else ""
        md.append(
            f"| **{c.id}**: {c.statement}{note} | {c.paper}, {c.source}, `{c.experiment}`{doc} | "
            f"{c.paper_value} | {v.ours} | **{v.verdict}**{diag} {md_figs} |"
        )
        imgs = "".join(
            f"<img alt='{html.escape(f)}' src='data:image/png;base64,"
            f"{base64.b64encode(p.read_bytes()).decode()}'>"
            for f, p in figs if p is not None
        )  # fmt: skip
        hb.append(
            f"<tr><td><b>{html.escape(c.id)}</b>: {html.escape(c.statement + note)}</td>"
            f"<td>{html.escape(f'{c.paper}, {c.source}')}<br><code>{html.escape(c.experiment)}"
            f"</code>{_discussed(c.discussion)}</td><td>{html.escape(c.paper_value)}</td>"
            f"<td>{html.escape(v.ours)}</td>"
            f"<td class='{v.verdict.replace(' ', '-')}'><b>{html.escape(v.verdict)}</b>{diag}</td>"
            f"<td>{imgs}</td></tr>"
        )
    return md, hb


def _not_pooled(failures: Sequence[tuple[Path, str]]) -> Section:
    """The runs left out of the pooled numbers, and why (its HTML closes the claims table)."""
    md = ["", "## Runs not pooled: failed, interrupted, set aside", ""]
    hb = ["</table><h2>Runs not pooled: failed, interrupted, set aside</h2>"]
    if failures:
        md += [f"* `{d}`: {e}" for d, e in failures]
        hb.append("<ul>" + "".join(
            f"<li><code>{html.escape(str(d))}</code>: {html.escape(str(e))}</li>"
            for d, e in failures) + "</ul>")  # fmt: skip
    else:
        md.append("None.")
        hb.append("<p>None.</p>")
    return md, hb


def _metrics_section(table: Any) -> Section:
    """Per experiment: every condition's metrics, mean ± 95 % CI over seeds."""
    md = ["", "## Metrics (mean ± 95 % CI over seeds)", ""]
    hb = ["<h2>Metrics (mean ± 95 % CI over seeds)</h2>"]
    head = "".join(f"<th>{h}</th>" for h in ("condition", "metric", "mean", "± CI", "n", "missing"))
    for exp, sub in table.groupby("experiment", sort=True):
        md += [
            f"### {exp}",
            "",
            "| condition | metric | mean | ± CI | n | missing |",
            "|---|---|---|---|---|---|",
        ]
        md += [f"| {r.condition} | {r.metric} | {_mean(r.mean)} | {_ci(r.ci95)} | {r.n} | "
               f"{r.missing} |" for r in sub.itertuples()]  # fmt: skip
        md.append("")
        hb.append(f"<details><summary>{html.escape(str(exp))}</summary><table><tr>{head}</tr>")
        hb += [f"<tr><td>{html.escape(str(r.condition))}</td><td>{html.escape(str(r.metric))}"
               f"</td><td>{_mean(r.mean)}</td><td>{_ci(r.ci95)}</td><td>{r.n}</td>"
               f"<td>{r.missing}</td></tr>"
               for r in sub.itertuples()]  # fmt: skip
        hb.append("</table></details>")
    return md, hb


def main(argv: Sequence[str]) -> int:
    """``ccm report DIR [--claims FILE]``: write DIR/report.md and DIR/report.html."""
    args = list(argv)
    if {"-h", "--help"} & set(args):
        print(
            "usage: ccm report DIR [--claims FILE]: report.md + report.html for the runs under DIR"
        )
        return 0
    claims = DEFAULT_CLAIMS
    if "--claims" in args:
        i = args.index("--claims")
        if i + 1 >= len(args):
            raise ConfigError("report.claims", "--claims needs a file")
        claims = Path(args.pop(i + 1))
        args.pop(i)
    if len(args) != 1:
        raise ConfigError("report", "usage: ccm report DIR [--claims FILE]")
    root = Path(args[0])
    if root.is_dir():  # before the work: a report it cannot write is one line, not a traceback
        check_output_dir("report.dir", root)
    screened = usable_runs(root)
    md, page = render(root, claims, screened)
    try:
        write_atomic(root / "report.md", md)
        write_atomic(root / "report.html", page)
    except OSError as exc:
        raise ConfigError("report.dir", f"cannot write the report: {exc}") from None
    print(f"ccm: report -> {root / 'report.html'} and report.md")
    runs, aside = screened
    if not any(s.get("status") == "ok" for _, s in runs):
        print(f"ccm: error: report.dir: no usable run under {root} ({tally(runs, aside)}); "
              "the report lists why", file=sys.stderr)  # fmt: skip
        return 1
    return 0

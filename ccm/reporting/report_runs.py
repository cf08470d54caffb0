"""The runs a report pools (``ccm report DIR``, :mod:`ccm.reporting.report`; issue #8).

:func:`collect` reads every ``summary.json`` under DIR (a malformed one is skipped with a
note; a run directory with its Hydra config but no summary.json is a failed run), and
:func:`with_run_info` adds the run's timing facts (``run_info.json``) to its conditions, so a
claim can compare rates measured in one process (seed B Table 2). :func:`usable_runs` screens
them (:mod:`ccm.reporting.report_screen`: duplicates, truncated runs beside full ones);
:func:`truncated` says which runs were cut short and :func:`by_seed` orders an experiment's
runs for its figures.
"""

from __future__ import annotations

import json
import sys
from collections.abc import Sequence
from pathlib import Path
from typing import Any

from ccm.core.errors import ConfigError
from ccm.core.records import read_json_object
from ccm.reporting.report_screen import SetAside, screen

__all__ = [
    "RUN_INFO_METRICS",
    "by_seed",
    "collect",
    "summary_problem",
    "truncated",
    "usable_runs",
    "with_run_info",
]


def collect(root: Path) -> list[tuple[Path, dict[str, Any]]]:
    """(run dir, summary) for every run under ``root``, sorted by path: each readable
    summary.json, and each run directory that has its Hydra config but no summary.json (a
    job killed before it wrote one), as a failed run of the experiment its config names."""
    if not root.is_dir():
        raise ConfigError("report.dir", f"{root} is not a directory")
    runs = []
    skipped = 0
    for path in sorted(root.rglob("summary.json")):
        try:
            summary = json.loads(path.read_text(encoding="utf-8"))
        except (OSError, ValueError) as exc:  # ValueError: bad JSON, or bytes that are not UTF-8
            runs.append((path.parent, {"status": "failed", "error": f"unreadable: {exc}"}))
            continue
        problem = summary_problem(summary)
        if problem is not None:  # valid JSON of another shape: nothing in it can be trusted
            print(f"ccm: note: skipped {path}: {problem}", file=sys.stderr)
            skipped += 1
            continue
        runs.append((path.parent, with_run_info(path.parent, summary)))
    for cfg in sorted(root.rglob(".hydra/config.yaml")):
        run = cfg.parent.parent
        if not (run / "summary.json").is_file():
            runs.append((run, _unfinished(cfg)))
    if not runs:
        what = f"usable summary.json under {root} ({skipped} malformed, skipped)"
        raise ConfigError("report.dir", f"no {what if skipped else f'summary.json under {root}'}")
    return sorted(runs, key=lambda r: str(r[0]))


_JSON_TYPES = {dict: "an object", list: "an array", str: "a string", bool: "a boolean"}


def _json_type(value: Any) -> str:
    if value is None:
        return "null"
    return _JSON_TYPES.get(type(value), "a number" if isinstance(value, int | float) else "?")


def summary_problem(summary: Any) -> str | None:
    """Why a parsed summary.json cannot be reported (the fields the report reads have the
    wrong JSON type), or None: an object whose ``conditions`` map names to objects, whose
    ``trials`` is a list of objects, ``run_info`` an object and ``experiment`` a string."""
    if not isinstance(summary, dict):
        return f"{_json_type(summary)}, not an object"
    checks = (("conditions", dict, dict), ("trials", list, dict), ("run_info", dict, None))
    for key, kind, item in checks:
        value = summary.get(key)
        if value is None:
            continue
        if not isinstance(value, kind):
            return f"'{key}' is {_json_type(value)}, not {_JSON_TYPES[kind]}"
        items = value.items() if isinstance(value, dict) else enumerate(value)
        bad = next(((k, v) for k, v in items if item and not isinstance(v, item)), None)
        if bad is not None:
            return f"'{key}' entry {bad[0]!r} is {_json_type(bad[1])}, not an object"
    if not isinstance(summary.get("experiment"), str | None):
        return f"'experiment' is {_json_type(summary['experiment'])}, not a string"
    return None


RUN_INFO_METRICS = (
    "mpc_rate_hz", "mpc_cpu_rate_hz", "mpc_iterations_median", "mpc_ms_per_iteration",
)  # fmt: skip


def with_run_info(run: Path, summary: dict[str, Any]) -> dict[str, Any]:
    """``summary`` with the run's per-condition wall-clock MPC facts (``RUN_INFO_METRICS`` of
    ``run_info.json``) added to its conditions, and the run's scalar wall-clock facts (e.g.
    H3's ``joint_multi_train_s``) under ``run_info``, where a claim reads them with
    ``condition: run_info``; unchanged without a readable run_info.json."""
    info = read_json_object(run / "run_info.json")
    conditions = summary.get("conditions")
    if info is None or not isinstance(conditions, dict):
        return summary
    for name in RUN_INFO_METRICS:
        per_condition = info.get(name)
        for cond, v in (per_condition if isinstance(per_condition, dict) else {}).items():
            if isinstance(conditions.get(cond), dict):
                conditions[cond][name] = v
    summary["run_info"] = {
        k: v for k, v in info.items() if isinstance(v, int | float) and not isinstance(v, bool)
    }
    return summary


def _hydra_config(run: Path) -> dict[str, Any]:
    """The run's composed config (``.hydra/config.yaml``), or {} without a readable one."""
    import yaml

    try:
        data = yaml.safe_load((run / ".hydra" / "config.yaml").read_text(encoding="utf-8"))
    except (OSError, ValueError, yaml.YAMLError):  # ValueError: bytes that are not UTF-8
        return {}
    return data if isinstance(data, dict) else {}


def truncated(run: Path) -> bool:
    """Whether the run's trials were cut short (``experiment.fast`` or ``max_time_s``)."""
    exp = _hydra_config(run).get("experiment")
    return isinstance(exp, dict) and (bool(exp.get("fast")) or exp.get("max_time_s") is not None)


def _unfinished(cfg: Path) -> dict[str, Any]:
    """The failed-run record of a run directory without summary.json."""
    data = _hydra_config(cfg.parent.parent)
    exp = data.get("experiment")
    return {
        "experiment": exp.get("name") if isinstance(exp, dict) else None,
        "seed": data.get("seed"),
        "status": "failed",
        "error": "no summary.json (the run did not finish)",
    }


def by_seed(runs: Sequence[tuple[Path, dict]], experiment: str) -> list[Path]:
    """The ok runs of ``experiment``, lowest seed first (then by path): the order in which
    the report looks for a claim's figures (the first run that has the file is shown)."""
    ok = [(s.get("seed", 0), d) for d, s in runs
          if s.get("experiment") == experiment and s.get("status") == "ok"]  # fmt: skip
    ok.sort(key=lambda x: (x[0] if isinstance(x[0], int) else 0, str(x[1])))
    return [d for _, d in ok]


def usable_runs(root: Path) -> tuple[list[tuple[Path, dict[str, Any]]], list[SetAside]]:
    """The runs under ``root`` the report pools, and those it sets aside
    (:mod:`ccm.reporting.report_screen`: duplicates, truncated runs beside full ones)."""
    return screen(collect(root), truncated)

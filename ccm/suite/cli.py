"""``ccm suite``: score a controller on a benchmark suite and rank it on the leaderboard.

    ccm suite controller=NAME [controller.KEY=VALUE …]   one entry over every task and seed
    ccm suite --list                                     the tasks, their protocol, the entries
    ccm suite --regenerate [ENTRY …]                     the built-in entries' stored results
    ccm suite --board                                    the stored results' leaderboard

Options: ``--suite NAME`` (default changing_contact_v1), ``--tasks a,b`` (a subset: quicker,
ranked on those tasks only), ``--jobs N`` (worker processes, default 2), ``--out DIR`` (a new
directory; default ``outputs/suite/<suite>/<entry>/<time>``), ``--name NAME`` (the entry's
name on the board; default the controller's), ``-cd/--config-dir DIR`` (the user's configs).
Exit 0 when every job ran, 1 when one failed (the board shows it), 2 on bad input.
"""

from __future__ import annotations

import sys
import time
from collections.abc import Sequence
from datetime import datetime
from pathlib import Path
from typing import Any

from ccm.core.errors import ConfigError, check_int_positive
from ccm.core.records import write_atomic, write_json_atomic
from ccm.experiment import user_configs
from ccm.suite import board as boards
from ccm.suite import render
from ccm.suite.definition import DEFAULT_SUITE, Suite, check_task_names, load_suite, results_dir
from ccm.suite.runner import precheck, run_entry, task_fingerprints

FLAGS = ("--suite", "--tasks", "--jobs", "--out", "--name")


def parse(args: Sequence[str]) -> dict[str, Any]:
    """The options (module docstring) and the Hydra overrides of a ``ccm suite`` line."""
    dirs, rest = user_configs.split_dir_flags(args)
    opts: dict[str, Any] = {"dirs": user_configs.check_dirs(dirs), "overrides": [],
                            "list": False, "regenerate": None}  # fmt: skip
    it = iter(rest)
    for a in it:
        flag, eq, value = a.partition("=")
        if flag in FLAGS:
            value = value if eq else next(it, None)
            if value is None or value.startswith("-"):
                raise ConfigError(flag, "needs a value")
            opts[flag[2:]] = value
        elif a == "--list":
            opts["list"] = True
        elif a in ("-h", "--help"):
            opts["help"] = True
        elif a == "--regenerate":
            opts["regenerate"] = []
        elif a == "--board":
            opts["board"] = True
        elif a.startswith("-"):
            raise ConfigError(a, f"unknown option; allowed: --list, --regenerate, --board, --help, "
                              f"{', '.join(FLAGS)}, --config-dir")  # fmt: skip
        elif opts["regenerate"] is not None and "=" not in a:
            opts["regenerate"].append(a)
        else:
            opts["overrides"].append(a)
    opts["jobs"] = check_int_positive("--jobs", _int("--jobs", opts.get("jobs", "2")))
    return opts


def _int(key: str, text: str) -> int | str:
    try:
        return int(text)
    except ValueError:
        return text  # check_int_positive names it


def main(args: Sequence[str]) -> int:
    """Entry point of ``ccm suite`` (ConfigError: the caller prints it, exit 2)."""
    opts = parse(args)
    if opts.get("help"):
        print("usage:\n" + __doc__.split("\n\n", 1)[1].replace("``", ""), end="")
        return 0
    suite = load_suite(opts.get("suite", DEFAULT_SUITE))
    tasks = check_task_names(suite, [t for t in opts.get("tasks", "").split(",") if t])
    if opts["list"]:
        print(listing(suite))
        return 0
    if opts["regenerate"] is not None:
        return regenerate(suite, tasks, opts)
    if opts.get("board"):
        store_board(suite, _out_dir(opts.get("out"), suite, "board"))
        return 0
    overrides = opts["overrides"]
    if not any(o.lstrip("+").partition("=")[0].startswith("controller") for o in overrides):
        raise ConfigError("controller", "ccm suite needs a controller: ccm suite controller=NAME "
                          "(ccm list shows them; --list shows the suite)")  # fmt: skip
    name = opts.get("name") or _entry_name(overrides)
    out = _out_dir(opts.get("out"), suite, name)
    results, failed = _run(suite, tasks, overrides, name, out, opts)
    stored = _usable_stored(suite, tasks, results["fingerprints"])
    mine = f"{name} (yours)"
    board = boards.rank_entries(suite, {**stored, mine: results}, tasks)
    _report(board, out, mine)
    return 1 if failed else 0


def _entry_name(overrides: Sequence[str]) -> str:
    for o in reversed(overrides):
        key, _, value = o.lstrip("+").partition("=")
        if key in ("controller", "controller._target_"):
            return value.rpartition(":")[2].rpartition(".")[2] or value
    return "controller"


def _out_dir(given: str | None, suite: Suite, name: str) -> Path:
    stamp = datetime.now().strftime("%Y-%m-%d_%H-%M-%S-%f")
    out = Path(given) if given else Path("outputs") / "suite" / suite.name / name / stamp
    if out.exists() and any(out.iterdir()):
        raise ConfigError("--out", f"{out} is not empty; give a new directory (nothing there is "
                          "overwritten)")  # fmt: skip
    return out


def _run(suite: Suite, tasks: Sequence[str], overrides: Sequence[str], name: str, out: Path,
         opts: dict[str, Any]) -> tuple[dict[str, Any], bool]:  # fmt: skip
    """Precheck, run the entry's jobs, write ``results.json`` and ``suite_info.json``."""
    prints = precheck(suite, tasks, overrides, opts["dirs"])
    out.mkdir(parents=True, exist_ok=True)
    n = len(tasks) * len(suite.seeds)
    print(f"ccm suite {suite.name}: {name} on {len(tasks)} tasks x {len(suite.seeds)} seeds "
          f"({suite.warmup_trials} warm-up + {suite.scored_trials} scored trials each), "
          f"{opts['jobs']} at a time -> {out}")  # fmt: skip
    done = []

    def progress(row: dict[str, Any]) -> None:
        done.append(row)
        tail = "" if row["status"] == "ok" else f": {row['error']}"
        print(f"  [{len(done)}/{n}] {row['task']} seed {row['seed']} {row['status']} "
              f"({row['wall_s']:.1f} s){tail}", flush=True)  # fmt: skip

    wall0 = time.perf_counter()
    rows = run_entry(suite, tasks, overrides, out, opts["dirs"], opts["jobs"], progress)
    wall = time.perf_counter() - wall0
    results = boards.entry_results(suite, name, overrides, rows, prints)
    write_json_atomic(out / "results.json", results)
    info = {"wall_time_s": wall, "jobs": opts["jobs"], "cpu_s": sum(r["cpu_s"] for r in rows),
            "per_job": [{k: r[k] for k in ("task", "seed", "status", "wall_s", "cpu_s")}
                        for r in rows]}  # fmt: skip
    write_json_atomic(out / "suite_info.json", info)
    print(f"ccm suite: {name} done in {wall / 60:.1f} min wall ({info['cpu_s'] / 60:.1f} CPU-min)")
    return results, any(r["status"] != "ok" for r in rows)


def _usable_stored(suite: Suite, tasks: Sequence[str],
                   prints: dict[str, str]) -> dict[str, dict[str, Any]]:  # fmt: skip
    """The stored entries, each task whose fingerprint differs from today's left out (one
    line each: those numbers are of another scene)."""
    out = {}
    for entry, res in boards.load_stored(suite).items():
        stale = boards.stale_tasks(res, prints)
        for t in stale:
            print(f"ccm suite: warning: stored {entry} on {t} is of another version of the task "
                  f"(fingerprint); left out. `ccm suite --regenerate {entry}` renews it",
                  file=sys.stderr)  # fmt: skip
        keep = {t: v for t, v in res["tasks"].items() if t in tasks and t not in stale}
        out[entry] = {**res, "tasks": keep}
    return out


def _report(board: boards.Board, out: Path, mine: str | None) -> None:
    paths = render.write_board(board, out, mine)
    title, note, head, rows = render.tables(board, mine)[0]
    width = max(len(r[1]) for r in rows)
    print(f"{title}  ({head[2]})")
    for r in rows:
        print(f"  {r[0]:>3}. {r[1]:<{width}}  {r[2]:>6}  tasks ok {r[3]}")
    names = ", ".join(str(p) for p in paths[:3])
    print(f"leaderboard: {names}; figures in {out / 'figures'}")


def regenerate(suite: Suite, tasks: Sequence[str], opts: dict[str, Any]) -> int:
    """Run the built-in entries (all, or those named) and store their results in the
    package (``ccm/suite/results/<suite>/<entry>.json``); then the board of all of them, also
    stored there as ``leaderboard.md``."""
    names = opts["regenerate"] or list(suite.entries)
    for n in names:
        if n not in suite.entries:
            raise ConfigError("--regenerate", f"unknown entry {n!r}; allowed: "
                              f"{', '.join(suite.entries)}")  # fmt: skip
    if list(tasks) != list(suite.tasks):
        raise ConfigError("--tasks", "stored results cover the whole suite: --regenerate runs "
                          "every task")  # fmt: skip
    out = _out_dir(opts.get("out"), suite, "regenerate")
    failed = False
    for n in names:
        results, bad = _run(suite, tasks, suite.entries[n], n, out / n, opts)
        failed |= bad
        results_dir(suite).mkdir(parents=True, exist_ok=True)
        write_json_atomic(results_dir(suite) / f"{n}.json", results)
    store_board(suite, out)
    return 1 if failed else 0


def store_board(suite: Suite, out: Path) -> None:
    """The leaderboard of the stored results (every task) into ``out``, and its Markdown
    beside them (``leaderboard.md``: derived from them, so always rewritten)."""
    tasks = list(suite.tasks)
    stored = _usable_stored(suite, tasks, task_fingerprints(suite, tasks))
    board = boards.rank_entries(suite, stored, tasks)
    _report(board, out, None)
    write_atomic(results_dir(suite) / "leaderboard.md", render.markdown(board, None))


def listing(suite: Suite) -> str:
    """``ccm suite --list``: the suite, its protocol, its tasks and the stored entries."""
    lines = [f"suite {suite.name} (version {suite.version}): {suite.description}",
             f"  seeds {', '.join(map(str, suite.seeds))}; per seed and task "
             f"{suite.warmup_trials} warm-up + {suite.scored_trials} scored trials, one "
             "controller throughout", "tasks:"]  # fmt: skip
    for name, t in suite.tasks.items():
        lines.append(f"  {name:<24} sim={t.sim} task={t.task}: {t.description}")
        lines.append(f"  {'':<24} ranks {', '.join(t.ranked)}")
    stored = boards.load_stored(suite)
    lines.append("built-in entries (stored results; `ccm suite --regenerate` renews them):")
    for name, ovs in suite.entries.items():
        mark = "" if name in stored else "  (not stored yet)"
        lines.append(f"  {name:<24} {' '.join(ovs)}{mark}")
    return "\n".join(lines)

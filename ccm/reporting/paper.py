"""``ccm paper``: every paper experiment as a Hydra multirun over its configured seeds, then
``ccm report`` (issue #8; ``make reproduce-paper``).

Each experiment is one ``ccm run -m experiment=<name> hydra/launcher=local`` sweep (its seeds
and other sweep axes come from the experiment config's ``hydra.sweeper.params``), writing to
``<out>/<name>/`` with its console output in ``<out>/<name>.log``. ``--lanes`` sweeps run at
once, longest first: a sweep with fewer jobs than workers, or the last job of an odd sweep,
would otherwise leave a core idle. Sweeps resume (finished runs are skipped), so running the
same command again after an interruption only does what is missing. ``--quick`` runs seed 0
with truncated trials (``experiment.fast=true``): a smoke test of the whole pipeline.
``--sim mujoco3d`` runs the 3-D experiments, and only those, on the MuJoCo backend (issue
#42: ``sim=mujoco3d`` appended to each sweep; every other setting is the experiment's).

Figures (issue #40): the trial-loop sweeps run with ``experiment.figures=false``; once they
are done, the figures of the runs the report shows (each experiment's lowest seed) are drawn
from their files, ``--lanes`` at a time (:mod:`ccm.plots.redraw`). ``ccm plots <out>/<name>``
draws the other runs' figures on request. The analyses draw their own figures in every run.

The wall time of every sweep and of the whole pipeline goes to ``<out>/paper_timing.json``.
"""

from __future__ import annotations

import argparse
import functools
import os
import resource
import subprocess
import sys
import time
from collections.abc import Sequence
from concurrent.futures import ThreadPoolExecutor
from pathlib import Path

from omegaconf import OmegaConf

from ccm.core.records import read_json_object, write_json_atomic
from ccm.experiment.config_check import check_output_dir
from ccm.experiment.user_configs import config_dir, group_options
from ccm.plots.redraw import draw_many
from ccm.reporting.report import main as report
from ccm.reporting.report_runs import by_seed, collect

# the paper experiments, longest first (job-seconds measured 2026-12-01 on 2 cores, for
# scheduling only): h3 5 x 380, h1_adaptive_control 10 x ~95, mpc_contact 5 x 100 (each of its
# two latency settings), ...
PAPER_EXPERIMENTS = (
    "h3_long_horizon", "h1_adaptive_control", "mpc_contact", "mpc_contact_latency",
    "h4_contact_learning", "h4_impactless", "h2_changing_surface", "mpc_rail", "h4_collisions",
    "gp_contact_models",
    "contact_head_to_head", "mpc_polishing", "mpc_table2", "mpc_goal_inference", "h1_forward_model",
    "h1_forward_model_one_step", "mpc_convexity", "h4_impact_design",
)  # fmt: skip

#: the 3-D backends ``--sim`` may put a 3-D experiment on
THREE_D_ENGINES = ("pybullet3d", "mujoco3d")


def sweep_command(
    name: str, out: Path, quick: bool, launcher: str = "local", force: bool = False,
    sim: str | None = None,
) -> list[str]:  # fmt: skip
    """The ``ccm run -m`` command line of one experiment's sweep (``force``: ``--force``,
    earlier records moved aside, :mod:`ccm.experiment.run_record`; ``sim``: another backend
    for it, ``sim=<name>``). A trial-loop sweep runs without figures:
    :func:`draw_shown_figures` draws those the report shows afterwards."""
    cmd = [sys.executable, "-m", "ccm.cli", "run", *["--force"] * force, "-m", f"experiment={name}"]
    if sim is not None:
        cmd.append(f"sim={sim}")
    if quick:
        cmd += ["seed=0", "experiment.fast=true"]
    if trial_loop(name):
        cmd.append("experiment.figures=false")
    return [*cmd, f"hydra/launcher={launcher}", f"hydra.sweep.dir={out / name}"]


@functools.cache
def experiment_sim(name: str) -> str:
    """The backend experiment ``name`` runs on (its composed ``sim.name``)."""
    from hydra import compose, initialize_config_dir

    with initialize_config_dir(str(config_dir()), version_base="1.3", job_name="ccm_paper"):
        return str(compose("config", overrides=[f"experiment={name}"]).sim.name)


def trial_loop(name: str) -> bool:
    """Whether experiment ``name`` is a trial loop (its figures can be drawn from its files,
    :mod:`ccm.plots.redraw`) rather than an analysis, which draws its own."""
    cfg = OmegaConf.load(config_dir() / "experiment" / f"{name}.yaml")
    return OmegaConf.select(cfg, "experiment.kind", default="trials") == "trials"


def draw_shown_figures(out: Path, names: Sequence[str], lanes: int) -> dict[str, float]:
    """Draw the figures of the runs the report shows (each trial-loop experiment's lowest
    seed, :func:`ccm.reporting.report_runs.by_seed`) that have none yet, ``lanes`` processes at a
    time; ``{"wall_s", "cpu_s"}`` (the workers' CPU included)."""
    t0, cpu0 = time.perf_counter(), _cpu_with_children()
    runs = collect(out)
    shown = [by_seed(runs, n)[:1] for n in names if trial_loop(n)]
    todo = [d for (d,) in filter(None, shown) if not any((d / "figures").glob("*.png"))]
    for run, n, error in draw_many(todo, lanes):
        print(f"ccm paper: figures: {error}" if error else f"ccm paper: {n} figures -> {run}")
    return {"wall_s": time.perf_counter() - t0, "cpu_s": _cpu_with_children() - cpu0}


def _cpu_with_children() -> float:
    """User + system CPU seconds of this process and of the children it has waited for."""
    usage = (resource.getrusage(who) for who in (resource.RUSAGE_SELF, resource.RUSAGE_CHILDREN))
    return sum(u.ru_utime + u.ru_stime for u in usage)


def _run_sweep(
    name: str, out: Path, args: argparse.Namespace, t0: float
) -> tuple[str, int, float, float]:
    """Run one sweep; ``(name, exit code, wall s, CPU s)``. The CPU time is the sweep
    process's user + system time and that of the workers it waited for (``wait4``: a local
    sweep's loky workers; a cluster's jobs are not counted)."""
    start = time.perf_counter()
    with open(out / f"{name}.log", "a", encoding="utf-8") as log:  # earlier invocations kept
        cmd = sweep_command(name, out, args.quick, args.launcher, args.force, args.sim)
        log.write(f"=== {time.strftime('%Y-%m-%d %H:%M:%S')}: {' '.join(cmd[1:])}\n")
        log.flush()
        proc = subprocess.Popen(cmd, stdout=log, stderr=subprocess.STDOUT)
        _, status, usage = os.wait4(proc.pid, 0)
        proc.returncode = rc = os.waitstatus_to_exitcode(status)
    took = time.perf_counter() - start
    cpu = usage.ru_utime + usage.ru_stime
    state = "ok" if rc == 0 else f"FAILED (exit {rc}; see {out / name}.log)"
    print(
        f"[{time.perf_counter() - t0:6.0f} s] {name}: {state} in {took:.0f} s "
        f"({cpu / 60:.1f} CPU-min)", flush=True,
    )  # fmt: skip
    return name, rc, took, cpu


def _record_timing(path: Path, entry: dict) -> None:
    """Write this invocation's wall times to ``path``; the invocations before it stay, under
    ``earlier`` (a resumed or partial ``ccm paper`` must not erase a full run's timing)."""
    earlier: list = []
    old = read_json_object(path)
    if old is not None:
        earlier = [*old.pop("earlier", []), old]
    write_json_atomic(path, {**entry, "earlier": earlier})


def main(argv: Sequence[str] | None = None) -> int:
    """Run the sweeps, then the report; exit 1 if any sweep or the report failed."""
    p = argparse.ArgumentParser(
        prog="ccm paper", description="Every paper experiment over its seeds, then the report."
    )
    p.add_argument("--out", type=Path, default=Path("outputs/paper"), help="output directory")
    p.add_argument("--lanes", type=int, default=2, help="sweeps run at once (default 2)")
    p.add_argument("--quick", action="store_true", help="seed 0, truncated trials")
    p.add_argument(
        "--force", action="store_true",
        help="start over: earlier records are moved aside (<dir>.replaced-<time>), not resumed",
    )  # fmt: skip
    p.add_argument(
        "--launcher", default="local",
        help="hydra/launcher preset for every sweep (local; slurm with --lanes 14 on a cluster)",
    )  # fmt: skip
    p.add_argument(
        "--sim", choices=THREE_D_ENGINES, default=None,
        help="run the 3-D experiments (and only those) on this 3-D backend instead "
        "(issue #42: mujoco3d beside the configs' pybullet3d)",
    )  # fmt: skip
    p.add_argument("experiments", nargs="*", help=f"default: all {len(PAPER_EXPERIMENTS)}")
    args = p.parse_args(argv)
    unknown = [e for e in args.experiments if e not in PAPER_EXPERIMENTS]
    if unknown:
        print(
            f"ccm paper: unknown experiment {unknown[0]!r}; allowed: "
            f"{', '.join(PAPER_EXPERIMENTS)}",
            file=sys.stderr,
        )
        return 2

    if args.launcher not in group_options("hydra/launcher"):
        allowed = ", ".join(group_options("hydra/launcher"))
        print(
            f"ccm paper: --launcher {args.launcher}: unknown; allowed: {allowed}", file=sys.stderr
        )
        return 2
    if args.lanes < 1:
        print(f"ccm paper: --lanes must be >= 1, got {args.lanes}", file=sys.stderr)
        return 2
    names = [e for e in PAPER_EXPERIMENTS if not args.experiments or e in args.experiments]
    if args.sim is not None:  # the 3-D experiments only: a 2-D one has no 3-D engine to swap
        names = [e for e in names if experiment_sim(e) in THREE_D_ENGINES]
    check_output_dir("paper --out", args.out)  # a file, or under one: one line (issue #19)
    args.out.mkdir(parents=True, exist_ok=True)
    t0 = time.perf_counter()
    print(f"ccm paper: {len(names)} sweeps, {args.lanes} at a time -> {args.out}", flush=True)
    with ThreadPoolExecutor(max_workers=args.lanes) as pool:
        results = list(pool.map(lambda n: _run_sweep(n, args.out, args, t0), names))
    figures = draw_shown_figures(args.out, names, args.lanes)
    report_rc = report([str(args.out)])
    wall = time.perf_counter() - t0
    failed = [n for n, rc, _, _ in results if rc != 0]
    _record_timing(
        args.out / "paper_timing.json",
        {"wall_s": round(wall, 1), "lanes": args.lanes, "quick": args.quick,
         "launcher": args.launcher, "sim": args.sim,
         "sweeps_s": {n: round(s, 1) for n, _, s, _ in results},
         "sweeps_cpu_s": {n: round(c, 1) for n, _, _, c in results},
         "figures_s": round(figures["wall_s"], 1), "figures_cpu_s": round(figures["cpu_s"], 1),
         "failed": failed},
    )  # fmt: skip
    print(f"ccm paper: {len(names) - len(failed)}/{len(names)} sweeps ok, wall {wall / 60:.1f} min")
    return 1 if failed or report_rc != 0 else 0

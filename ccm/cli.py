"""The ``ccm`` command: ``ccm run [overrides]``, ``ccm run -m …``, ``ccm list``, ``ccm --help``.

``ccm run`` hands its arguments to a Hydra app (``version_base="1.3"``). Before Hydra creates a
run directory, every override combination is composed and every component built once, so a
bad override ends with one line naming the key and what is allowed, and exit code 2.
"""

from __future__ import annotations

import json
import os
import sys
from collections.abc import Sequence
from pathlib import Path
from typing import TYPE_CHECKING

import ccm
from ccm.experiment import jobdir, user_configs
from ccm.experiment.composer import Composer
from ccm.experiment.precheck import compose_extra, precheck, yaml_line
from ccm.experiment.trust import TRUST_FLAG
from ccm.experiment.user_configs import (  # noqa: F401 - also importable from here
    GROUPS,
    config_dir,
    group_options,
)

jobdir.register()  # hydra.sweep.subdir names jobs through it, here and in launcher workers

if TYPE_CHECKING:
    from omegaconf import DictConfig

EXIT_CONFIG = 2
EXIT_FAILED = 1

HELP = """\
usage: ccm <command> [args]

commands:
  run [OVERRIDES]       run an experiment (Hydra overrides, e.g. experiment=smoke seed=3)
  run -m [OVERRIDES]    multirun sweep, e.g. ccm run -m experiment=smoke seed=0,1,2
  run --force …         start over where a record is (it moves to <dir>.replaced-<time>)
  run -cd DIR …         also use the configs in DIR (--config-dir; or hydra.searchpath=[…])
  run --trust-configs … let configs name callables other than ccm's and Hydra's own
                        (hydra.callbacks, launchers, logging): configs are code
  list [-cd DIR]        the experiments, tasks, controllers and sims the config groups offer
  report DIR            report.md + report.html for the runs under DIR (a run or a sweep):
                        the papers' claims with verdicts (experiments/claims.yaml), metrics
                        over seeds, failures; --claims FILE for another claims file
  paper [--quick]       every paper experiment over its seeds (2 sweeps at a time), then
                        report (make reproduce-paper); --out DIR, --lanes N, names to select,
                        --force to start over (earlier records moved aside, not resumed),
                        --sim mujoco3d the 3-D experiments only, on MuJoCo
  compare-engines A B   the 3-D claims' verdicts of two paper runs (PyBullet, MuJoCo) side
                        by side -> B/cross_engine.md
  plots DIR…            draw a finished run's figures again from its files (a sweep
                        directory: each of its runs, --jobs N at a time)
  animate RUN_DIR       a clip of one recorded trial (MP4; GIF with --out x.gif), replayed
                        from its time series: --condition C (default the first), --trial N
                        (default the last recorded), --out FILE, --fps F
  suite [OVERRIDES]     score a controller on the changing-contact benchmark and rank it
                        against the built-in ones: ccm suite controller=NAME; --list shows
                        the tasks and protocol, --tasks a,b a subset, --jobs N workers,
                        --regenerate the built-in results (ccm/suite/cli.py)
  demo TASK --out FILE  record one demonstration of a task in simulation (seed B's
                        simulated human guides the robot in admittance mode) as CSV or
                        Parquet, for a pattern {type: recording, file: FILE}; --seed N,
                        Hydra overrides
  --help, -h            this message; `ccm run --help` shows Hydra's help and the config
  --version             print the version

Outputs go to ./outputs/<experiment>/<timestamp>/ (sweeps: ./multirun/…), relative to the
current directory: .hydra/, timeseries/, plot_inputs.json, run_info.json, summary.json,
then figures/*.png (drawn after the numbers are written).
Set HYDRA_FULL_ERROR=1 (or pass --verbose to `run`) for full tracebacks.
"""


def describe(group: str, option: str, dirs: Sequence[Path] = ()) -> str:
    """The ``description`` field of a group option, or its first comment line; a file whose
    top level is not a mapping raises ConfigError naming it."""
    from omegaconf import DictConfig, OmegaConf

    from ccm.core.errors import ConfigError

    path = user_configs.option_file(group, option, dirs, user_configs.config_dir())
    node = OmegaConf.load(path)
    if not isinstance(node, DictConfig):
        raise ConfigError(str(path), "the top level is a list; a config is a mapping of keys")
    desc = OmegaConf.select(node, "description", default=None)
    if desc is None:
        desc = OmegaConf.select(node, f"{group}.description", default=None)
    if desc is None:
        for line in path.read_text(encoding="utf-8").splitlines():
            if line.startswith("#") and "@package" not in line:
                return line.lstrip("# ").strip()
    return str(desc or "")


def cmd_list(args: Sequence[str] = ()) -> int:
    """``ccm list [--config-dir DIR]``: every option of the main groups, with its line."""
    import yaml

    from ccm.core.errors import ConfigError

    try:
        flagged, rest = user_configs.split_dir_flags(args)
        dirs = user_configs.check_dirs(flagged)
    except ConfigError as exc:
        return _fail(str(exc), EXIT_CONFIG)
    if rest:
        return _fail(f"list: unexpected {rest[0]!r}; usage: ccm list [--config-dir DIR]", 2)
    broken = 0
    for group in ("experiment", "task", "controller", "sim"):
        print(f"{group}:")
        for opt in user_configs.group_options(group, dirs):
            try:
                text = describe(group, opt, dirs)
            except (yaml.YAMLError, ConfigError) as exc:  # named, the rest still listed
                broken += 1
                line = str(exc) if isinstance(exc, ConfigError) else yaml_line(exc)
                text = f"(unreadable: {line})"
            print(f"  {opt:<28} {text}")
    broken += list_plugins()
    return EXIT_CONFIG if broken else 0


def list_plugins() -> int:
    """Print the plugins that installed packages register (``ccm.controllers``,
    ``ccm.simulators``, ``ccm.segments`` entry points), each loaded and checked; return how
    many are broken (each named with its one-line reason)."""
    from ccm.control.registry import CONTROLLERS, controller_class
    from ccm.core import plugins
    from ccm.core.errors import ConfigError
    from ccm.sim import BACKENDS, sim_class
    from ccm.tasks.trajectory import SEGMENTS, segment_class

    checks = {
        "controller": (CONTROLLERS, lambda name: controller_class({"type": name})),
        "sim": (BACKENDS, lambda name: sim_class({"name": name})),
        "segment": (SEGMENTS, lambda name: segment_class({"type": name}, "task.pattern[]")),
    }
    broken = 0
    for kind, group in plugins.GROUPS.items():
        builtins, load = checks[kind]
        found = plugins.plugin_entry_points(kind)
        print(f"{kind} plugins (entry points {group}):" + ("" if found else " none installed"))
        for name, target in found.items():
            if name in builtins:
                broken += 1
                print(f"  {name:<28} {target}: not used, {name!r} is a built-in {kind}")
                continue
            try:
                load(name)
                print(f"  {name:<28} {target}")
            except ConfigError as exc:
                broken += 1
                print(f"  {name:<28} {target}: broken: {exc}")
    return broken


def _fail(message: str, code: int) -> int:
    print(f"ccm: error: {message}", file=sys.stderr)
    return code


def _job(cfg) -> None:  # noqa: ANN001 - DictConfig, kept untyped for Hydra's signature check
    """The Hydra task function: lock and check the run directory (:mod:`ccm.experiment.run_record`),
    run the experiment, or record the failure or interruption and exit non-zero."""
    from hydra.core.hydra_config import HydraConfig
    from hydra.types import RunMode

    from ccm.experiment.interrupts import RunInterrupted, job_signals
    from ccm.experiment.run_record import RecordRefused
    from ccm.experiment.sweep_check import mark_refused

    hc = HydraConfig.get()
    out_dir = Path(hc.runtime.output_dir)
    multirun = hc.mode == RunMode.MULTIRUN
    try:
        with job_signals(multirun):
            _open_and_run(cfg, out_dir, multirun)
    except RecordRefused as exc:
        print(f"ccm: error: {exc}", file=sys.stderr)
        if not multirun:
            sys.exit(EXIT_CONFIG)
        mark_refused(Path(hc.sweep.dir), out_dir, str(exc))
    except RunInterrupted as exc:
        if multirun:  # ccm run prints the line once the sweep has stopped
            raise
        print(f"ccm: interrupted ({exc.name}); partial record in {out_dir}", file=sys.stderr)
        sys.exit(exc.exit_code)


def _open_and_run(cfg: DictConfig, out_dir: Path, multirun: bool) -> None:
    """Open the run directory's record (locked, config checked), then skip a finished run or
    write ``.hydra/`` and run."""
    from hydra.core.hydra_config import HydraConfig

    from ccm.experiment.run_record import RecordRefused, forced, ok_summary, open_record

    with open_record(out_dir, cfg, force=forced()) as record:
        if record.replaced is not None:
            print(f"ccm: --force: the previous record moved aside -> {record.replaced}")
        done = ok_summary(out_dir)
        if done is not None:  # resume: a finished run is never redone or overwritten
            print(f"ccm: {done.get('experiment')} already ok -> {out_dir} (skipped; --force "
                  "runs it again)")  # fmt: skip
            return
        hc = HydraConfig.get()
        try:
            record.write_hydra(HydraConfig.instance().cfg, hc.overrides.task)
        except OSError as exc:  # a full disk, a quota (issue #39: a traceback)
            raise RecordRefused(
                f"run directory {out_dir}: cannot write its record ({exc.strerror or exc}); "
                "free space there or choose another directory"
            ) from None
        _run_locked(cfg, out_dir, list(hc.overrides.task), multirun)


def _run_locked(cfg: DictConfig, out_dir: Path, task_overrides: list[str], multirun: bool) -> None:
    """Run the experiment into the locked ``out_dir``; a failure or an interruption is written
    to summary.json (status ``failed`` / ``interrupted``) before it ends the run."""
    from hydra.core.hydra_config import HydraConfig
    from threadpoolctl import threadpool_limits

    from ccm.analyses.dispatch import run
    from ccm.core.errors import ConfigError, SimulationDiverged
    from ccm.core.records import write_json_atomic
    from ccm.experiment.interrupts import RunInterrupted, record_interrupt
    from ccm.experiment.runner import failed_summary

    finished: list[dict] = []  # the trial loop's records, kept if the run is interrupted
    try:
        # one BLAS thread per job (cfg.blas_threads): parallel sweep workers must not
        # oversubscribe the cores, and the same count everywhere keeps results identical.
        # threadpoolctl limits only the BLAS libraries already loaded: scipy's own OpenBLAS
        # (GP fits, L-BFGS-B) is loaded here first, else it kept its default thread count
        import scipy.linalg  # noqa: F401

        with threadpool_limits(limits=int(cfg.get("blas_threads") or 1)):
            # conditions derive from the job's config, composed anew only to change a group
            choices = HydraConfig.get().runtime.choices
            composer = Composer(
                lambda extra: compose_extra(task_overrides, extra, hydra_node=True), cfg, choices
            )
            summary = run(cfg, composer, out_dir, finished=finished)
    except RunInterrupted as exc:
        record_interrupt(out_dir, cfg, exc, finished)
        raise
    except Exception as exc:
        expected = isinstance(exc, ConfigError | SimulationDiverged)
        message = str(exc) if expected else f"{type(exc).__name__}: {exc}"
        write_json_atomic(out_dir / "summary.json", failed_summary(cfg, message))
        if not expected and os.environ.get("HYDRA_FULL_ERROR") == "1":
            raise
        print(f"ccm: run failed: {message} [{out_dir}]", file=sys.stderr)
        if multirun:  # Hydra goes on; SweepCheck makes cmd_run exit 1
            return
        sys.exit(EXIT_FAILED)
    _print_summary(summary, out_dir)


def _print_summary(summary: dict, out_dir: Path) -> None:
    print(f"ccm: {summary['experiment']} {summary['status']} -> {out_dir}")
    rates = {}
    if (out_dir / "run_info.json").is_file():  # wall-clock facts live outside summary.json
        rates = json.loads((out_dir / "run_info.json").read_text()).get("mpc_rate_hz") or {}
    for name, metrics in summary["conditions"].items():
        parts = [f"{k}={v:.4g}" for k, v in metrics.items() if isinstance(v, float) and k in _SHOWN]
        if rates.get(name):
            parts.append(f"mpc_rate_hz={rates[name]:.3g}")
        print(f"  {name:<20} " + "  ".join(parts))


_SHOWN = (
    "rms_tracking_error_m", "peak_force_N", "mean_stiffness_Npm", "completion_time_s",
    "joint_pred_rmse_rad", "force_pred_rmse_N", "coverage_95", "convex_above_sigma_f",
    "contact_losses", "force_oscillation_rms_N", "mpc_infeasible", "rms_vel_low_mps",
    "rms_vel_high_mps", "damping_ratio_varied_repeatable", "belief_correct_final",
    "time_to_belief_s", "contact_position_error_m", "stiffness_ratio", "pred_std_contact_N",
)  # fmt: skip


def cmd_run(args: Sequence[str]) -> int:
    """``ccm run``: precheck, then the Hydra app; SIGINT/SIGTERM end it with one line."""
    from ccm.experiment import interrupts, run_record, sweep_check

    args = list(args)
    if "--verbose" in args:
        args.remove("--verbose")
        os.environ["HYDRA_FULL_ERROR"] = "1"
    sweep_check.ACTIVE.clear()
    try:
        with run_record.forcing("--force" in args), interrupts.launcher_env():
            with interrupts.interrupts_raise(interrupts.stop_local_workers):
                return _run_app([a for a in args if a != "--force"])
    except interrupts.RunInterrupted as exc:
        where = sweep_check.ACTIVE.get("sweep_dir")
        tail = f"; partial records in {where}" if where else ""
        print(f"ccm: interrupted ({exc.name}){tail}", file=sys.stderr)
        return exc.exit_code


def _run_app(args: list[str]) -> int:
    """Precheck the overrides (exit 2 on a bad one), then run the Hydra app; the user's config
    directories are searched first throughout (:mod:`ccm.experiment.user_configs`)."""
    from ccm.core.errors import ConfigError
    from ccm.experiment import run_record

    trusted = TRUST_FLAG in args
    args = [a for a in args if a != TRUST_FLAG]
    multirun = "-m" in args or "--multirun" in args
    flags = {"-m", "--multirun"}
    info_flags = {"--help", "-h", "--hydra-help", "--cfg", "-c", "--info", "-i", "--resolve"}
    try:
        flagged, rest = user_configs.split_dir_flags(args)
        overrides = [a for a in rest if not a.startswith("-") and a not in flags]
        dirs = [*user_configs.check_dirs(flagged),
                *user_configs.check_dirs(user_configs.searchpath_dirs(overrides),
                                         user_configs.SEARCHPATH)]  # fmt: skip
    except ConfigError as exc:
        return _fail(str(exc), EXIT_CONFIG)
    with run_record.scoped_env(user_configs.DIRS_ENV, os.pathsep.join(map(str, dirs))):
        if not (set(args) & info_flags):
            err = precheck(overrides, multirun, dirs, trusted)
            if err:
                return _fail(err, EXIT_CONFIG)
        return _hydra_app(args)


def _hydra_app(args: list[str]) -> int:
    """Run the Hydra app on ``args``; 1 if a job of a sweep failed."""
    import hydra

    config_path = str(user_configs.config_dir())
    app = hydra.main(version_base="1.3", config_path=config_path, config_name="config")(_job)
    saved = sys.argv
    sys.argv = ["ccm run", *args]
    from ccm.experiment import sweep_check

    sweep_check.FAILED_JOBS.clear()
    try:
        app()
    finally:
        sys.argv = saved
    return EXIT_FAILED if sweep_check.FAILED_JOBS else 0


def main(argv: Sequence[str] | None = None) -> int:
    """Entry point of the ``ccm`` console script."""
    argv = list(sys.argv[1:] if argv is None else argv)
    if not argv or argv[0] in ("-h", "--help", "help"):
        print(HELP, end="")
        return 0 if argv else EXIT_CONFIG
    if argv[0] == "--version":
        print(f"ccm {ccm.__version__}")
        return 0
    if argv[0] == "list":
        return cmd_list(argv[1:])
    if argv[0] == "run":
        return cmd_run(argv[1:])
    if argv[0] in ("report", "paper", "plots", "animate", "demo", "suite", "compare-engines"):
        from ccm.analyses.demo import main as demo
        from ccm.core.errors import ConfigError
        from ccm.plots.animate import main as animate
        from ccm.plots.redraw import main as plots
        from ccm.reporting.cross_engine import main as compare_engines
        from ccm.reporting.paper import main as paper
        from ccm.reporting.report import main as report
        from ccm.suite.cli import main as suite

        try:
            commands = {
                "report": report,
                "paper": paper,
                "plots": plots,
                "animate": animate,
                "demo": demo,
                "suite": suite,
                "compare-engines": compare_engines,
            }
            return commands[argv[0]](argv[1:])
        except ConfigError as exc:
            return _fail(str(exc), EXIT_CONFIG)
    return _fail(
        f"unknown command {argv[0]!r}; allowed: run, list, report, paper, plots, animate, demo, "
        "suite, compare-engines, --help",
        EXIT_CONFIG,
    )


if __name__ == "__main__":
    sys.exit(main())

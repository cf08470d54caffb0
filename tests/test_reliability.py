"""Reliability suite (issue #8): a catalogue of malformed configs and overrides.

Every case must end with ONE meaningful stderr line, ``ccm: error: …`` (exit 2, found before
any run directory exists) or ``ccm: run failed: …`` (exit 1, summary.json says ``failed``),
naming the offending key, and no traceback unless ``--verbose`` / ``HYDRA_FULL_ERROR=1``.

The catalogue runs in-process (``ccm.cli.main`` with capsys: the same code path and exit code
as the console script, without ~1-2 s of interpreter and Hydra start-up per case); a handful
of cases, the YAML syntax error, the sweep and ``--verbose`` run as real subprocesses.

Known harmless stderr/stdout noise, filtered explicitly (:data:`NOISE`): pybullet's
``pybullet build time: …`` banner, printed by its C extension when it is imported.
"""

from __future__ import annotations

import json
import os
import re
import shutil
import subprocess
import sys
from pathlib import Path

import pytest

import ccm.cli as cli
import ccm.experiment.user_configs as user_configs

CCM = str(Path(sys.executable).parent / "ccm")
NOISE = (re.compile(r"^pybullet build time:"),)

SMOKE = ["experiment=smoke"]
# one condition, no phases or condition overrides: the GP-MPC controller as the command line sets it
GP_MPC = ["experiment=single", "controller=gp_mpc", "task=mpc_contact", "experiment.fast=true"]
MPC_CONTACT = ["experiment=mpc_contact"]
SINGLE = ["experiment=single"]  # one condition: an error line has no "(condition …)"
TABLE_WALL = ["experiment=single", "sim=pybullet3d", "task=table_wall"]


def case(
    case_id: str, expected: str, base: list[str], *overrides: str, marks: object = ()
) -> object:
    """One catalogue entry: ``base + overrides`` must fail with ``expected`` in its line."""
    return pytest.param([*base, *overrides], expected, id=case_id, marks=marks)


# case(id, substring the one error line must contain, base overrides, *overrides)
CATALOGUE = [
    # unknown config group options
    case("group-controller", "controller=nope: unknown option", [], "controller=nope"),
    case("group-task", "task=nope: unknown option", [], "task=nope"),
    case("group-sim", "sim=nope: unknown option", [], "sim=nope"),
    case("group-experiment", "experiment=nope: unknown option", [], "experiment=nope"),
    # unknown keys
    case("key-controller", "controller.nonsense: unknown key", SMOKE, "controller.nonsense=1"),
    case(
        "key-controller-added", "controller.nonsense: unknown key", SMOKE, "+controller.nonsense=1"
    ),
    case("key-scene", "task.scene.nonsense: unknown key", SMOKE, "task.scene.nonsense=1"),
    case("key-sensor", "sim.sensor.nonsense: unknown key", SMOKE, "sim.sensor.nonsense=1"),
    case("key-experiment", "experiment.nonsense: unknown key", SMOKE, "experiment.nonsense=1"),
    # wrong types and malformed override syntax
    case(
        "type-stiffness-str",
        "controller.stiffness: must be a number",
        SMOKE,
        "controller.stiffness=abc",
    ),
    case(
        "type-stiffness-empty",
        "controller.stiffness: must be a number",
        SMOKE,
        "controller.stiffness=",
    ),
    case("syntax-override", "controller.stiffness=[1,: ", SMOKE, "controller.stiffness=[1,"),
    case("type-dt-list", "sim.dt: must be a number", SMOKE, "sim.dt=[1,2]"),
    case(
        "type-trials-float", "experiment.trials: must be an integer", SMOKE, "experiment.trials=1.5"
    ),
    case(
        "type-decimation",
        "sim.control_decimation: must be an integer",
        SMOKE,
        "sim.control_decimation=1.5",
    ),
    case("type-seed-list", "seed: must be an integer", SMOKE, "seed=[1]"),
    # NaN, infinite, negative and zero gains and steps
    case(
        "gain-inf",
        "controller.stiffness: must be a finite number",
        SMOKE,
        "controller.stiffness=inf",
    ),
    case("gain-negative", "controller.stiffness: must be > 0", SMOKE, "controller.stiffness=-1"),
    case("gain-zero", "controller.stiffness: must be > 0", SMOKE, "controller.stiffness=0"),
    case(
        "gain-in-condition",
        "controller.stiffness: must be > 0, got -5 (condition fixed_high)",
        SMOKE,
        "experiment.conditions.fixed_high=['controller=fixed_impedance','controller.stiffness=-5']",
    ),  # fmt: skip
    case(
        "damping-negative",
        "controller.loop.damping: must be >= 0",
        SMOKE,
        "controller.loop.damping_rule=fixed",
        "controller.loop.damping=-5",
    ),
    case(
        "damping-ratio-negative",
        "controller.loop.damping_ratio: must be > 0",
        SMOKE,
        "controller.loop.damping_ratio=-1",
    ),
    case(
        "nominal-mass-zero",
        "controller.loop.mass_kg: must be > 0",
        SMOKE,
        "controller.loop.mass_kg=0",
    ),
    case("dt-negative", "sim.dt: must be > 0", SMOKE, "sim.dt=-0.001"),
    case("dt-nan", "sim.dt: must be a finite number", SMOKE, "sim.dt=nan"),
    case("max-speed-negative", "sim.max_speed: must be > 0", SMOKE, "sim.max_speed=-1"),
    case(
        "noise-negative",
        "sim.sensor.force_noise_std: must be >= 0",
        SMOKE,
        "sim.sensor.force_noise_std=-0.1",
    ),
    case(
        "bias-length",
        "sim.sensor.force_bias: must have length 2",
        SMOKE,
        "sim.sensor.force_bias=[1]",
    ),
    # empty or non-monotone trajectories
    case(
        "segment-duration-negative",
        "task.pattern[0].duration: must be > 0",
        SMOKE,
        "task.pattern.0.duration=-0.3",
    ),
    case(
        "segment-duration-zero",
        "task.pattern[1].duration: must be > 0",
        SMOKE,
        "task.pattern.1.duration=0",
    ),
    case(
        "segment-type", "task.pattern[0].type: unknown value", SMOKE, "task.pattern.0.type=spiral"
    ),
    case(
        "segment-target-length",
        "task.pattern[0].to: must have length 2",
        SMOKE,
        "task.pattern.0.to=[0.05]",
    ),
    case(
        "segment-target-nan",
        "task.pattern[0].to: must be finite",
        SMOKE,
        "task.pattern.0.to=[nan,0]",
    ),
    case("start-length", "task.start: must have length 2", SMOKE, "task.start=[0,0,0]"),
    # impossible scenes
    case("ee-mass-zero", "task.scene.ee.mass: must be > 0", SMOKE, "task.scene.ee.mass=0"),
    case(
        "ee-size-zero", "task.scene.ee.size[0]: must be > 0", SMOKE, "task.scene.ee.size=[0,0.05]"
    ),
    case(
        "spring-negative",
        "task.scene.springs[0].stiffness: must be > 0",
        SMOKE,
        "task.scene.springs.0.stiffness=-40",
    ),
    case(
        "spring-rest-negative",
        "task.scene.springs[0].rest_length: must be >= 0",
        SMOKE,
        "task.scene.springs.0.rest_length=-1",
    ),
    case(
        "wall-normal-zero",
        "task.scene.compliant_walls[0].normal: must be a non-zero vector",
        MPC_CONTACT,
        "task.scene.compliant_walls.0.normal=[0,0]",
    ),
    case(
        "wall-stiffness-negative",
        "task.scene.compliant_walls[0].stiffness: must be > 0",
        MPC_CONTACT,
        "task.scene.compliant_walls.0.stiffness=-1",
    ),
    case(
        "human-goal-index",
        "task.scene.human.goal_index: must be an integer in [0, 1]",
        [],
        "experiment=single",
        "task=mpc_goal_inference",
        "task.scene.human.goal_index=5",
    ),
    # seed-B (GP-MPC) controller settings
    case(
        "mpc-force-delay",
        "controller.force_delay_s: must be >= 0",
        MPC_CONTACT,
        "controller.force_delay_s=-1",
    ),
    case(
        "mpc-horizon-zero",
        "controller.mpc.horizon",
        GP_MPC,
        "controller.mpc.horizon=0",
    ),
    case("mpc-ts-negative", "controller.mpc.ts", GP_MPC, "controller.mpc.ts=-1"),
    case(
        "mpc-well-damped-zeta",
        "controller.mpc.well_damped",
        GP_MPC,
        "controller.mpc.well_damped={zeta: -1}",
    ),
    case(
        "mpc-mass-bounds-zero",
        "controller.mpc.mass_bounds",
        GP_MPC,
        "controller.mpc.mass_bounds=[0,10]",
    ),
    # experiment settings
    case(
        "condition-unknown-key",
        "nonexistent_group: unknown key",
        SMOKE,
        "experiment.conditions.fixed_low=['nonexistent_group=1']",
    ),
    case(
        "condition-unknown-option",
        "controller=nope",
        SMOKE,
        "experiment.conditions.fixed_low=['controller=nope']",
    ),
    case(
        "condition-bad-value",
        "controller.stiffness: must be > 0",
        SMOKE,
        "experiment.conditions.fixed_high=['controller.stiffness=-1']",
    ),
    case("phases-not-list", "experiment.phases: must be a list", SMOKE, "experiment.phases=3"),
    case(
        "phase-unknown-key",
        "experiment.phases[0]: must be a mapping with keys",
        SMOKE,
        "experiment.phases=[{name: a, trials: 1, nope: 1}]",
    ),
    case(
        "phase-trials-zero",
        "experiment.phases[0].trials: must be an integer >= 1",
        SMOKE,
        "experiment.phases=[{name: a, trials: 0, overrides: []}]",
    ),
    case(
        "phase-bad-override",
        "sim.dt: must be > 0",
        SMOKE,
        "experiment.phases=[{name: a, trials: 1, overrides: ['sim.dt=-1']}]",
    ),
    case(
        "metric-unknown",
        "experiment.metrics: unknown metric 'nope'",
        SMOKE,
        "experiment.metrics=[nope]",
    ),
    case("kind-unknown", "experiment.kind: must be one of", SMOKE, "experiment.kind=nope"),
    case(
        "max-time-negative", "experiment.max_time_s: must be > 0", SMOKE, "experiment.max_time_s=-1"
    ),
    case(
        "settle-negative",
        "experiment.settle_time_s: must be >= 0",
        SMOKE,
        "experiment.settle_time_s=-1",
    ),
    case("lowpass-negative", "metrics.lowpass_hz: must be > 0", SMOKE, "metrics.lowpass_hz=-1"),
    case(
        "init-from-missing",
        "init_from: '/nonexistent/dir' is not a directory",
        SMOKE,
        "init_from=/nonexistent/dir",
    ),
    # issue #19: trials shorter than a few control steps
    case(
        "trial-shorter-than-steps-dt",
        "task.pattern: a trial of 0.9 s (pattern + experiment.settle_time_s) is 0 control steps "
        "of 1 s (sim.dt",
        SINGLE,
        "sim.dt=1.0",
    ),
    case(
        "trial-shorter-than-steps-max-time",
        "experiment.max_time_s: a trial of 1e-09 s is 0 control steps",
        SINGLE,
        "experiment.max_time_s=1e-9",
    ),
    case(
        "timeseries-bits-out-of-range",
        "experiment.timeseries_bits: must be an integer from 8 to 23",
        SINGLE,
        "experiment.timeseries_bits=30",
    ),
    # booleans (tests/test_reliability.py::test_every_boolean_field_is_validated: all of them)
    case(
        "bool-fast-no",
        "experiment.fast: must be true or false, got 'no'",
        SINGLE,
        "experiment.fast=no",
    ),
    case(
        "bool-fast-maybe", "experiment.fast: must be true or false", SINGLE, "experiment.fast=maybe"
    ),
    case(
        "bool-fast-2", "experiment.fast: must be true or false, got 2", SINGLE, "experiment.fast=2"
    ),
    case(
        "bool-figures-off",
        "experiment.figures: must be true or false",
        SINGLE,
        "experiment.figures=off",
    ),
    # names that become directories
    case("name-dotdot", "experiment.name: may use letters", SINGLE, "experiment.name=../../x"),
    case("name-slash", "experiment.name: may use letters", SINGLE, "experiment.name=a/b"),
    case("name-long", "experiment.name: may use letters", SINGLE, f"experiment.name={'x' * 300}"),
    case("job-name-long", "hydra.job.name: ", SINGLE, f"hydra.job.name={'x' * 300}"),
    # impossible starts
    case(
        "start-in-box-2d",
        "task.start: the end-effector at [0, 0] overlaps task.scene.boxes[0]",
        SINGLE,
        "task.scene.boxes=[{center: [0.01, 0], size: [0.2, 0.2]}]",
    ),
    case(
        "start-in-box-2d-rotated",
        "task.start: the end-effector at [0.07, 0] overlaps task.scene.boxes[0]",
        SINGLE,
        "task.start=[0.07, 0, 0.785]",
        "task.scene.boxes=[{center: [0.1, 0], size: [0.05, 0.05]}]",
    ),
    case(
        "start-in-box-3d",
        "task.start: the tool point [0.65, 0, 0.05] is inside task.scene.boxes[0]",
        TABLE_WALL,
        "task.start=[0.65, 0, 0.05]",
    ),
    case(
        "start-in-table-3d",
        "task.start: the tool point [0.48, -0.1, 0.05] is inside task.scene.table",
        TABLE_WALL,
        "task.start=[0.48, -0.1, 0.05]",
    ),
    # misleading messages
    case(
        "task-2d-on-3d-sim",
        "task.dim: task=smoke is a 2-D task, for sim=pymunk2d; sim=pybullet3d simulates 3-D",
        SINGLE,
        "sim=pybullet3d",
    ),
    case(
        "task-3d-on-2d-sim",
        "task.dim: task=table_wall is a 3-D task, for sim=pybullet3d; sim=pymunk2d simulates 2-D",
        SINGLE,
        "task=table_wall",
    ),
    case("seed-negative", "seed: must be an integer >= 0, got -1", SINGLE, "seed=-1"),
]


def meaningful(text: str) -> list[str]:
    """Non-empty lines that are not known harmless noise (:data:`NOISE`)."""
    return [ln for ln in text.splitlines() if ln.strip() and not any(p.match(ln) for p in NOISE)]


def check_one_line(code: int, out: str, err: str, expected: str, run_dir: Path) -> None:
    """The contract every bad input must meet (module docstring)."""
    assert code != 0, f"exit code 0; stdout: {out!r}"
    assert "Traceback" not in out and "Traceback" not in err
    lines = meaningful(err)
    assert len(lines) == 1, err
    (line,) = lines
    assert line.startswith(("ccm: error: ", "ccm: run failed: ")), line
    assert expected in line
    summary = run_dir / "summary.json"
    if line.startswith("ccm: error: "):
        assert code == cli.EXIT_CONFIG
        assert not run_dir.exists(), "a config error must stop before the run directory"
    elif summary.is_file():  # a run that started records its failure
        data = json.loads(summary.read_text())
        assert data["status"] == "failed"
        assert data["error"]


@pytest.fixture
def no_full_error(monkeypatch: pytest.MonkeyPatch) -> None:
    monkeypatch.delenv("HYDRA_FULL_ERROR", raising=False)


def run_in_process(args: list[str], capsys: pytest.CaptureFixture[str]) -> tuple[int, str, str]:
    try:
        code = cli.main(args)
    except SystemExit as exc:  # _job exits 1 from inside Hydra on a failed single run
        code = exc.code if isinstance(exc.code, int) else 1
    cap = capsys.readouterr()
    return code, cap.out, cap.err


def test_catalogue_is_large_enough() -> None:
    assert len(CATALOGUE) >= 30
    assert len({p.id for p in CATALOGUE}) == len(CATALOGUE)


@pytest.mark.usefixtures("no_full_error")
@pytest.mark.parametrize(("overrides", "expected"), CATALOGUE)
def test_bad_input_is_one_line_in_process(
    tmp_path: Path, capsys: pytest.CaptureFixture[str], overrides: list[str], expected: str
) -> None:
    run_dir = tmp_path / "run"
    code, out, err = run_in_process(["run", *overrides, f"hydra.run.dir={run_dir}"], capsys)
    check_one_line(code, out, err, expected, run_dir)


def ccm(args: list[str], cwd: Path, **env: str) -> subprocess.CompletedProcess[str]:
    environ = {k: v for k, v in os.environ.items() if k != "HYDRA_FULL_ERROR"} | env
    return subprocess.run(
        [CCM, *args], cwd=cwd, env=environ, capture_output=True, text=True, timeout=120, check=False
    )


SUBPROCESS_IDS = ("key-sensor", "type-stiffness-str", "ee-mass-zero", "mpc-force-delay")
SUBPROCESS_CASES = [p for p in CATALOGUE if p.id in (*SUBPROCESS_IDS, "phase-bad-override")]


@pytest.mark.parametrize(("overrides", "expected"), SUBPROCESS_CASES)
def test_bad_input_is_one_line_as_console_script(
    tmp_path: Path, overrides: list[str], expected: str
) -> None:
    run_dir = tmp_path / "run"
    res = ccm(["run", *overrides, f"hydra.run.dir={run_dir}"], tmp_path)
    check_one_line(res.returncode, res.stdout, res.stderr, expected, run_dir)


def test_diverging_simulation_fails_with_its_cause(tmp_path: Path) -> None:
    """A huge gain on the 1 kg block runs away within a few steps: exit 1, one line naming the
    runaway guard, summary.json ``failed`` with the cause."""
    run_dir = tmp_path / "run"
    res = ccm(["run", *SMOKE, "controller.stiffness=1e9", f"hydra.run.dir={run_dir}"], tmp_path)
    assert res.returncode == cli.EXIT_FAILED
    check_one_line(res.returncode, res.stdout, res.stderr, "exceeds sim.max_speed", run_dir)
    (line,) = meaningful(res.stderr)
    assert line.startswith("ccm: run failed: end-effector speed")
    summary = json.loads((run_dir / "summary.json").read_text())
    assert summary["status"] == "failed"
    assert "exceeds sim.max_speed" in summary["error"]


def test_failed_job_of_a_sweep_is_one_line(tmp_path: Path) -> None:
    """One failing job in a sweep: the other job still runs, the failure is one line (no
    Hydra "Error executing job" block), and the sweep exits 1."""
    sweep = tmp_path / "sweep"
    res = ccm(
        ["run", "-m", *SMOKE, "experiment.fast=true", "sim.max_speed=0.01,20",
         f"hydra.sweep.dir={sweep}"],
        tmp_path,
    )  # fmt: skip
    assert res.returncode == cli.EXIT_FAILED
    assert "Traceback" not in res.stdout + res.stderr
    assert "Error executing job" not in res.stdout + res.stderr
    lines = meaningful(res.stderr)
    assert len(lines) == 1, res.stderr
    assert lines[0].startswith("ccm: run failed: ") and "sim.max_speed=0.01" in lines[0]
    status = {
        p.parent.name: json.loads(p.read_text())["status"] for p in sweep.rglob("summary.json")
    }
    # job directories are named by their overrides (configs/config.yaml, hydra.sweep.subdir)
    assert sorted(status.items()) == [
        ("experiment.fast=True,experiment=smoke,sim.max_speed=0.01", "failed"),
        ("experiment.fast=True,experiment=smoke,sim.max_speed=20", "ok"),
    ]


# A config file with a YAML syntax error: an unquoted ${...} inside a flow list.
BAD_YAML = """\
# @package _global_
experiment:
  name: bad_yaml
  conditions:
    a: [task.scene.ee.mass=${sim.dt}]
"""

RUN_WITH_CONFIGS = (
    "import sys; from pathlib import Path; import ccm.cli as c, ccm.experiment.user_configs as u; "
    "u.config_dir = lambda: Path(sys.argv[1]); sys.exit(c.main(sys.argv[2:]))"
)


@pytest.fixture
def bad_yaml_configs(tmp_path: Path) -> Path:
    configs = tmp_path / "configs"
    shutil.copytree(cli.config_dir(), configs)
    (configs / "experiment" / "bad_yaml.yaml").write_text(BAD_YAML)
    return configs


def test_yaml_syntax_error_is_one_line(tmp_path: Path, bad_yaml_configs: Path) -> None:
    run_dir = tmp_path / "run"
    args = ["run", "experiment=bad_yaml", f"hydra.run.dir={run_dir}"]
    res = subprocess.run(
        [sys.executable, "-c", RUN_WITH_CONFIGS, str(bad_yaml_configs), *args],
        cwd=tmp_path,
        env={k: v for k, v in os.environ.items() if k != "HYDRA_FULL_ERROR"},
        capture_output=True,
        text=True,
        timeout=120,
        check=False,
    )
    check_one_line(res.returncode, res.stdout, res.stderr, "bad_yaml.yaml:5:", run_dir)
    assert "YAML syntax error" in res.stderr

    # --verbose (HYDRA_FULL_ERROR=1) shows the traceback
    res = subprocess.run(
        [sys.executable, "-c", RUN_WITH_CONFIGS, str(bad_yaml_configs), "run", "--verbose",
         *args[1:]],
        cwd=tmp_path, capture_output=True, text=True, timeout=120, check=False,
    )  # fmt: skip
    assert res.returncode != 0
    assert "Traceback" in res.stderr
    assert "yaml.parser.ParserError" in res.stderr


def test_list_names_an_unreadable_config(
    bad_yaml_configs: Path, monkeypatch: pytest.MonkeyPatch, capsys: pytest.CaptureFixture
) -> None:
    monkeypatch.setattr(user_configs, "config_dir", lambda: bad_yaml_configs)
    assert cli.main(["list"]) == cli.EXIT_CONFIG
    out = capsys.readouterr().out
    (line,) = [x for x in out.splitlines() if "bad_yaml" in x]
    assert "unreadable" in line and "bad_yaml.yaml:5:" in line and "YAML syntax error" in line
    assert "smoke" in out  # the other options are still listed

"""Reliability catalogue, part 2 (issue #19): the cases that need more than one ``ccm run``
line of overrides - sweeps and launchers, output directories, sweep job names, every boolean
field, and ``ccm report`` / ``ccm list`` / ``ccm paper`` on bad input.

The contract is the one of tests/test_reliability.py (:func:`check_one_line`): one
``ccm: error: …`` line naming the key, exit 2, no traceback, no run or sweep directory.
"""

from __future__ import annotations

import os
import shutil
from pathlib import Path
from typing import Any

import pytest
from test_reliability import ccm as ccm_process
from test_reliability import check_one_line, meaningful, run_in_process

import ccm.cli as cli
import ccm.experiment.user_configs as user_configs
from ccm.experiment.jobdir import job_dir_name

FAST = ["experiment=smoke", "experiment.fast=true", "experiment.figures=false"]
ROOT = os.geteuid() == 0  # root writes into read-only directories: those cases need a user

pytestmark = pytest.mark.usefixtures("no_full_error")


@pytest.fixture
def no_full_error(monkeypatch: pytest.MonkeyPatch) -> None:
    monkeypatch.delenv("HYDRA_FULL_ERROR", raising=False)


def _one_error(code: int, err: str, expected: str) -> None:
    """Exit 2 and exactly one ``ccm: error:`` line containing ``expected``."""
    assert code == cli.EXIT_CONFIG, err
    assert "Traceback" not in err
    (line,) = meaningful(err)
    assert line.startswith("ccm: error: ") and expected in line, line


# --------------------------------------------------------------------------- sweeps, launchers


@pytest.mark.parametrize(
    ("overrides", "expected"),
    [
        pytest.param(["seed=range(0,0)"], "seed=range(0,0): the sweep is empty", id="empty"),
        pytest.param(
            ["hydra/launcher=local", "hydra.launcher.n_jobs=0"],
            "hydra.launcher.n_jobs: must be a non-zero integer",
            id="n-jobs-zero",
        ),
        pytest.param(["hydra/launcher=slurm"], "hydra/launcher: slurm needs", id="no-srun"),
    ],
)
def test_bad_sweep_settings_are_one_line(
    tmp_path: Path,
    capsys: pytest.CaptureFixture[str],
    monkeypatch: pytest.MonkeyPatch,
    overrides: list[str],
    expected: str,
) -> None:
    monkeypatch.setenv("PATH", str(tmp_path / "no-bin"))  # no srun/sbatch, whatever the host
    sweep = tmp_path / "sweep"
    args = ["run", "-m", *FAST, *overrides, f"hydra.sweep.dir={sweep}"]
    code, out, err = run_in_process(args, capsys)
    check_one_line(code, out, err, expected, sweep)


def test_job_dir_names_are_safe_and_bounded() -> None:
    assert job_dir_name("experiment=smoke,seed=1") == "experiment=smoke,seed=1"  # unchanged
    slashed = job_dir_name("experiment.description=a/../../b")
    assert "/" not in slashed and slashed.startswith("experiment.description=a_.._.._b~")
    assert job_dir_name("x=a/b") != job_dir_name("x=a_b")  # no two jobs share a directory
    long = job_dir_name("x=" + "é" * 300)
    assert len(long.encode()) <= 255 and long != job_dir_name("x=" + "é" * 301)
    assert job_dir_name("..") not in ("..", ".")


def test_sweep_jobs_stay_inside_the_sweep_directory(tmp_path: Path) -> None:
    """A '/' or '..' in an override value and a 300-character value: both jobs run, each in
    a directory directly under the sweep directory, named within 255 bytes."""
    sweep = tmp_path / "sweep" / "inner"
    values = f"a/../../b,{'x' * 300}"
    res = ccm_process(["run", "-m", *FAST, f"experiment.description={values}",
               f"hydra.sweep.dir={sweep}"], tmp_path)  # fmt: skip
    assert res.returncode == 0, res.stderr
    jobs = sorted(p.parent for p in tmp_path.rglob("summary.json"))
    assert len(jobs) == 2
    for job in jobs:
        assert job.parent == sweep
        assert len(job.name.encode()) <= 255


# --------------------------------------------------------------------------- booleans


def _bool_keys(node: Any, prefix: str = "") -> list[str]:
    if not isinstance(node, dict):
        return []
    out = []
    for k, v in node.items():
        key = f"{prefix}{k}"
        out += [key] if isinstance(v, bool) else _bool_keys(v, f"{key}.")
    return out


def _bool_fields() -> list[Any]:
    """A case per boolean field of the shipped configs (hydra's own left out): the overrides
    that select a file holding it, with the field set to ``maybe``."""
    from omegaconf import OmegaConf

    root = cli.config_dir()
    seen: dict[str, list[str]] = {}
    for path in sorted(root.rglob("*.yaml")):
        group = path.parent.relative_to(root).as_posix()
        if group.startswith("hydra"):
            continue
        data = OmegaConf.to_container(OmegaConf.load(path))
        for key in _bool_keys(data):
            full = key if group in (".", "experiment") else f"{group.replace('/', '.')}.{key}"
            # a nested group (controller/loop) comes with its parent's default option
            pick = [] if group == "." or "/" in group else [f"{group}={path.stem}"]
            three_d = data.get("dim") == 3 or path.stem in ("pybullet3d", "mujoco3d")
            if three_d:
                pick += ["sim=pybullet3d"] if group == "task" else ["task=table_wall"]
            if not full.startswith("hydra") and full not in seen:
                seen[full] = [*pick, f"{full}=maybe"]
    return [pytest.param(ovs, full, id=full) for full, ovs in seen.items()]


BOOL_FIELDS = _bool_fields()


def test_the_boolean_catalogue_covers_the_known_fields() -> None:
    ids = {p.id for p in BOOL_FIELDS}
    assert {"experiment.fast", "experiment.figures", "controller.adaptive", "sim.gui",
            "controller.loop.inertia_feedforward", "task.scene.ee.rotate"} <= ids  # fmt: skip


@pytest.mark.parametrize(("overrides", "key"), BOOL_FIELDS)
def test_every_boolean_field_is_validated(
    tmp_path: Path, capsys: pytest.CaptureFixture[str], overrides: list[str], key: str
) -> None:
    run_dir = tmp_path / "run"
    args = ["run", "experiment=single", *overrides, f"hydra.run.dir={run_dir}"]
    code, out, err = run_in_process(args, capsys)
    check_one_line(code, out, err, f"{key}: must be true or false, got 'maybe'", run_dir)


# --------------------------------------------------------------------------- output paths


@pytest.fixture
def a_file(tmp_path: Path) -> Path:
    path = tmp_path / "a_file"
    path.write_text("not a directory\n")
    return path


@pytest.mark.parametrize(
    ("where", "expected"),
    [
        pytest.param("a_file", "is a file, not a directory", id="file"),
        pytest.param("a_file/run", "is under", id="under-file"),
        pytest.param("x" * 300, "a path component is 300 bytes long", id="name-too-long"),
    ],
)
@pytest.mark.parametrize("multirun", [False, True], ids=["run", "sweep"])
def test_unusable_output_directory_is_one_line(
    tmp_path: Path,
    a_file: Path,
    capsys: pytest.CaptureFixture[str],
    where: str,
    expected: str,
    multirun: bool,
) -> None:
    out_dir = tmp_path / where
    key = "hydra.sweep.dir" if multirun else "hydra.run.dir"
    args = ["run", *(["-m"] if multirun else []), *FAST, f"{key}={out_dir}"]
    code, _, err = run_in_process(args, capsys)
    _one_error(code, err, f"{key}: ")
    assert expected in err
    assert a_file.read_text() == "not a directory\n"


@pytest.mark.skipif(ROOT, reason="root writes into read-only directories")
@pytest.mark.parametrize("multirun", [False, True], ids=["run", "sweep"])
def test_read_only_output_directory_is_one_line(
    tmp_path: Path, capsys: pytest.CaptureFixture[str], multirun: bool
) -> None:
    ro = tmp_path / "ro"
    ro.mkdir(mode=0o555)
    key = "hydra.sweep.dir" if multirun else "hydra.run.dir"
    args = ["run", *(["-m"] if multirun else []), *FAST, f"{key}={ro / 'run'}"]
    code, _, err = run_in_process(args, capsys)
    _one_error(code, err, f"{key}: ")
    assert "is not writable" in err


# --------------------------------------------------------------------------- report


GOOD = '{"experiment": "smoke", "status": "ok", "seed": 0, "conditions": {"a": {"x": 1.0}}}'
MALFORMED = [
    "[1, 2, 3]", '"hello"', '{"conditions": [1, 2]}', '{"status": "ok", "conditions": {"a": 1}}'
]  # fmt: skip


@pytest.mark.parametrize("text", MALFORMED)
def test_report_skips_a_malformed_summary(
    tmp_path: Path, capsys: pytest.CaptureFixture[str], text: str
) -> None:
    """Alone it leaves nothing usable (exit 2); next to a good run it is one note line."""
    bad = tmp_path / "runs" / "bad" / "summary.json"
    bad.parent.mkdir(parents=True)
    bad.write_text(text)
    code, _, err = run_in_process(["report", str(tmp_path / "runs")], capsys)
    assert code == cli.EXIT_CONFIG and "Traceback" not in err
    note, line = meaningful(err)
    assert note.startswith(f"ccm: note: skipped {bad}: ") and "not" in note
    assert line.startswith("ccm: error: report.dir: no usable summary.json")

    good = tmp_path / "runs" / "good" / "summary.json"
    good.parent.mkdir()
    good.write_text(GOOD)
    code, _, err = run_in_process(["report", str(tmp_path / "runs")], capsys)
    assert code == 0 and meaningful(err) == [note]
    assert (tmp_path / "runs" / "report.md").is_file()


@pytest.mark.skipif(ROOT, reason="root writes into read-only directories")
def test_report_on_a_read_only_directory_is_one_line(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    (tmp_path / "runs" / "r").mkdir(parents=True)
    (tmp_path / "runs" / "r" / "summary.json").write_text(GOOD)
    (tmp_path / "runs").chmod(0o555)
    code, _, err = run_in_process(["report", str(tmp_path / "runs")], capsys)
    _one_error(code, err, "report.dir: ")
    assert "not writable" in err


def test_report_that_cannot_be_written_is_one_line(
    tmp_path: Path, capsys: pytest.CaptureFixture[str], monkeypatch: pytest.MonkeyPatch
) -> None:
    """The write itself failing (a full disk; read-only as root cannot be staged)."""
    import ccm.reporting.report

    def refuse(path: Path, text: str) -> None:
        raise PermissionError(13, "Permission denied", str(path))

    monkeypatch.setattr(ccm.reporting.report, "write_atomic", refuse)
    (tmp_path / "r").mkdir()
    (tmp_path / "r" / "summary.json").write_text(GOOD)
    code, _, err = run_in_process(["report", str(tmp_path)], capsys)
    _one_error(code, err, "report.dir: cannot write the report: ")


# --------------------------------------------------------------------------- list, paper


def test_list_names_a_config_whose_top_level_is_a_list(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch, capsys: pytest.CaptureFixture[str]
) -> None:
    configs = tmp_path / "configs"
    shutil.copytree(cli.config_dir(), configs)
    (configs / "task" / "listed.yaml").write_text("- 1\n- 2\n")
    monkeypatch.setattr(user_configs, "config_dir", lambda: configs)
    code, out, err = run_in_process(["list"], capsys)
    assert code == cli.EXIT_CONFIG and "Traceback" not in out + err
    (line,) = [x for x in out.splitlines() if "listed" in x]
    assert f"(unreadable: {configs / 'task' / 'listed.yaml'}: the top level is a list" in line
    assert "smoke" in out  # the other options are still listed


@pytest.mark.parametrize(("where", "expected"), [("a_file", "is a file"), ("a_file/x", "under")])
def test_paper_out_that_is_not_a_directory_is_one_line(
    tmp_path: Path, a_file: Path, capsys: pytest.CaptureFixture[str], where: str, expected: str
) -> None:
    code, _, err = run_in_process(
        ["paper", "--out", str(tmp_path / where), "h4_collisions"], capsys
    )
    _one_error(code, err, "paper --out: ")
    assert expected in err

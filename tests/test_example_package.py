"""The example plugin package (issue #41, part 5), installed as a user installs it (into a
directory of its own, so the rest of the suite sees no plugin), then its README's commands:
its own contract test, ``ccm run --config-dir``, ``ccm suite`` (on two of the suite's tasks
here: the whole suite takes minutes, its figure is in the README) and the Gymnasium rollout;
and ``ccm list``, which the README mentions."""

from __future__ import annotations

import json
import os
import subprocess
import sys
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]
EXAMPLE = ROOT / "examples" / "my_controller"
BIN = Path(sys.executable).parent


@pytest.fixture(scope="module")
def installed(tmp_path_factory: pytest.TempPathFactory) -> dict[str, str]:
    """The environment of a shell where the example package is installed."""
    target = tmp_path_factory.mktemp("site")
    subprocess.run(
        [sys.executable, "-m", "pip", "install", "--quiet", "--disable-pip-version-check",
         "--no-deps", "--target", str(target), str(EXAMPLE)],
        check=True, capture_output=True, text=True, timeout=600,
    )  # fmt: skip
    return {**os.environ, "PYTHONPATH": str(target)}


def _run(args: list[str], env: dict[str, str], cwd: Path) -> subprocess.CompletedProcess:
    return subprocess.run(args, env=env, cwd=cwd, capture_output=True, text=True, timeout=600)


def test_ccm_list_shows_its_config_and_its_entry_point(installed, tmp_path: Path) -> None:
    res = _run([str(BIN / "ccm"), "list", "--config-dir", str(EXAMPLE / "configs")],
               installed, tmp_path)  # fmt: skip
    assert res.returncode == 0, res.stderr
    assert "  my_pd                        force-limited impedance" in res.stdout
    assert "  my_pd                        my_controller.ctrl:ForceLimitedImpedance" in res.stdout


def test_its_own_contract_test_passes(installed, tmp_path: Path) -> None:
    res = _run([sys.executable, "-m", "pytest", "-q", "-p", "no:cacheprovider",
                str(EXAMPLE / "tests")], installed, ROOT)  # fmt: skip
    assert res.returncode == 0, res.stdout[-2000:]
    assert "12 passed" in res.stdout  # six checks on each of two backends


def test_ccm_run_with_its_config_dir(installed, tmp_path: Path) -> None:
    res = _run([str(BIN / "ccm"), "run", "--config-dir", str(EXAMPLE / "configs"),
                "experiment=single", "task=multi_spring", "controller=my_pd",
                "experiment.figures=false"], installed, tmp_path)  # fmt: skip
    assert res.returncode == 0, res.stderr
    (summary,) = (tmp_path / "outputs" / "single").glob("*/summary.json")
    data = json.loads(summary.read_text())
    assert data["status"] == "ok" and list(data["conditions"]) == ["my_pd"]


def test_the_gymnasium_rollout(installed, tmp_path: Path) -> None:
    res = _run([sys.executable, str(EXAMPLE / "gym_rollout.py")], installed, tmp_path)
    assert res.returncode == 0, res.stderr
    assert res.stdout.startswith("ccm/MultiSpring-v0: 6000 steps, return ")


def test_ccm_suite_ranks_it_beside_the_built_in_controllers(installed, tmp_path: Path) -> None:
    """README step 4 on two tasks: my_pd is on the leaderboard with every stored entry."""
    import csv

    res = _run([str(BIN / "ccm"), "suite", "--config-dir", str(EXAMPLE / "configs"),
                "controller=my_pd", "--tasks", "contact,multi_spring", "--out", "board"],
               installed, tmp_path)  # fmt: skip
    assert res.returncode == 0, res.stderr
    rows = list(csv.DictReader((tmp_path / "board" / "leaderboard.csv").open()))
    entries = {r["entry"] for r in rows}
    assert "my_pd (yours)" in entries and {"fixed_impedance", "avic", "gp_mpc"} <= entries
    mine = [r for r in rows if r["entry"] == "my_pd (yours)" and r["ranked"] == "1"]
    assert mine and all(r["status"] == "ok" and r["rank"] for r in mine)
    assert "my_pd (yours)" in (tmp_path / "board" / "leaderboard.md").read_text()

"""``ccm suite`` (issue #41, part 3) end to end: the shipped suite's tasks and stored results,
a user's entry ranked against stored ones, failures that leave the rest of the suite whole,
bad input as one line, and results that do not depend on the number of workers.

Most cases run a small suite file written here (the smoke task, two seeds), so they take
seconds; one runs a task of the shipped suite."""

from __future__ import annotations

import csv
import json
from pathlib import Path

import pytest

from ccm.cli import main
from ccm.suite.board import load_stored, rank_entries
from ccm.suite.definition import load_suite, results_dir
from ccm.suite.render import markdown
from ccm.suite.runner import precheck, task_fingerprints

PLUGINS = "tests.plugins.controllers"
TINY = """\
name: tiny
version: 1
description: two short tasks for the tests
seeds: [5, 6]
warmup_trials: 1
scored_trials: 1
metrics:
  rms_tracking_error_m: {label: RMS tracking error, short: tracking, unit: m}
  effort_Ns: {label: effort, short: effort, unit: N s}
  energy_J: {label: energy, short: energy, unit: J}
  peak_contact_force_N: {label: peak contact force, short: peak force, unit: N}
  force_overshoot_N: {label: overshoot, short: overshoot, unit: N}
  contact_losses: {label: contact losses, short: losses, unit: count}
  time_to_complete_s: {label: time, short: time, unit: s}
tasks:
  smoke:
    description: the smoke task
    sim: pymunk2d
    task: smoke
    settings: {sim.sensor.force_noise_std: 0.05}
    ranked: [rms_tracking_error_m, effort_Ns]
  springs:
    description: the springs, 6.5 s
    sim: pymunk2d
    task: multi_spring
    ranked: [rms_tracking_error_m, energy_J]
entries:
  low: [controller=fixed_impedance]
  high: [controller=fixed_impedance_high]
"""


@pytest.fixture
def tiny(tmp_path: Path) -> Path:
    path = tmp_path / "suites" / "tiny.yaml"
    path.parent.mkdir()
    path.write_text(TINY)
    return path


def _suite(tiny: Path, out: Path, *args: str) -> int:
    return main(["suite", "--suite", str(tiny), "--out", str(out), "--jobs", "1", *args])


def test_list_shows_every_task_of_the_issue_and_the_protocol(capsys) -> None:  # noqa: ANN001
    """The issue's tasks: the springs, the porridge, the changing surface, the collisions, the
    table and wall, seed B's contact with and without latency, and the polishing."""
    assert main(["suite", "--list"]) == 0
    out = capsys.readouterr().out
    for name in ("multi_spring", "porridge", "changing_surface", "collisions", "table_wall",
                 "contact ", "contact_latency", "polishing"):  # fmt: skip
        assert f"  {name}" in out
    assert "seeds 1000, 1001, 1002, 1003, 1004" in out and "3 warm-up + 2 scored" in out
    suite = load_suite()
    assert suite.tasks["contact_latency"].settings["sim.sensor.delay_steps"] == 4
    assert {t.sim for t in suite.tasks.values()} == {"pymunk2d", "pybullet3d"}


def test_an_entry_is_ranked_against_the_stored_ones(tiny: Path, tmp_path: Path) -> None:
    """--regenerate stores the built-in entries beside the suite file; a user's entry is then
    ranked against them: a PD plugin with the low preset's gains has its numbers, and the
    leaderboard (MD, HTML, CSV, a figure per ranked metric) shows all three."""
    assert _suite(tiny, tmp_path / "regen", "--regenerate") == 0
    stored = load_stored(load_suite(str(tiny)))
    assert sorted(stored) == ["high", "low"]
    assert (results_dir(load_suite(str(tiny))) / "low.json").is_file()
    out = tmp_path / "mine"
    assert _suite(tiny, out, "controller=plugin", f"controller._target_={PLUGINS}:PlainPD",
                  "--name", "pd") == 0  # fmt: skip
    res = json.loads((out / "results.json").read_text())
    assert res["entry"] == "pd" and res["tasks"]["smoke"]["status"] == "ok"
    assert set(res["tasks"]["smoke"]["seeds"]) == {"5", "6"}
    md = (out / "leaderboard.md").read_text()
    assert "| 1 | high |" in md and "pd (yours)" in md and "| low |" in md
    rows = list(csv.DictReader((out / "leaderboard.csv").open()))
    assert {r["entry"] for r in rows} == {"pd (yours)", "low", "high"}
    html = (out / "leaderboard.html").read_text()
    assert html.count("class='mine'") == 3  # its row in the overall table and in each task's
    assert html.count("<tr class='mine'><td>pd (yours)</td>") == 2  # a task row starts with it
    figs = sorted(p.name for p in (out / "figures").glob("*.png"))
    assert figs == ["effort_Ns.png", "energy_J.png", "rms_tracking_error_m.png"]
    # the stiffer preset tracks better on the springs: the ranking reads the numbers
    high = [r for r in rows if r["entry"] == "high" and r["task"] == "springs"]
    low = [r for r in rows if r["entry"] == "low" and r["task"] == "springs"]
    track = "rms_tracking_error_m"
    assert float(next(r for r in high if r["metric"] == track)["mean"]) < float(
        next(r for r in low if r["metric"] == track)["mean"]
    )
    assert next(r for r in high if r["metric"] == track)["rank"] == "1.0"


def test_a_raising_plugin_fails_its_task_and_the_rest_goes_on(
    tiny: Path, tmp_path: Path, capsys
) -> None:  # noqa: ANN001
    """The plugin raises after 2 s of a trial: the springs (6.5 s) fail, with the cause in each
    seed's summary.json and on the board; the smoke task (0.9 s) runs; exit 1."""
    out = tmp_path / "raise"
    code = _suite(tiny, out, "controller=plugin", f"controller._target_={PLUGINS}:RaisesMidRun",
                  "+controller.fail_after_s=2.0")  # fmt: skip
    assert code == 1
    res = json.loads((out / "results.json").read_text())
    assert res["tasks"]["smoke"]["status"] == "ok"
    assert res["tasks"]["springs"]["status"] == "failed"
    assert "RuntimeError: the plugin's own bug" in res["tasks"]["springs"]["error"]
    for seed in (5, 6):
        summary = json.loads(
            (out / "runs" / "springs" / f"seed_{seed}" / "summary.json").read_text()
        )
        assert summary["status"] == "failed" and "the plugin's own bug" in summary["error"]
    assert "failed: seed 5: RuntimeError" in (out / "leaderboard.md").read_text()
    assert "springs seed 6 failed" in capsys.readouterr().out


@pytest.mark.parametrize(
    ("args", "line"),
    [
        ([], "controller: ccm suite needs a controller"),
        (["controller=nope"], "controller=nope: unknown option; allowed: aic, avic"),
        (["controller=fixed_impedance", "sim.dt=0.01"], "sim.dt: ccm suite takes controller "
                                                        "overrides only"),
        (["controller=fixed_impedance", "controller.stiffness=-3"], "controller.stiffness"),
        (["controller=plugin", "controller._target_=no.such:Thing"], "no.such"),
        (["controller=fixed_impedance", "--tasks", "nope"], "--tasks: unknown task 'nope'"),
        (["controller=fixed_impedance", "--jobs", "0"], "--jobs: must be an integer >= 1"),
        (["controller=fixed_impedance", "--frobnicate"], "--frobnicate: unknown option"),
    ],
)  # fmt: skip
def test_bad_input_is_one_line_and_writes_nothing(
    tiny: Path, tmp_path: Path, capsys, args: list, line: str
) -> None:  # noqa: ANN001
    out = tmp_path / "bad"
    assert _suite(tiny, out, *args) == 2
    err = capsys.readouterr().err.strip()
    assert len(err.splitlines()) == 1 and line in err, err
    assert not out.exists()


def test_unknown_suite_and_a_full_out_dir_are_refused(tmp_path: Path, capsys) -> None:  # noqa: ANN001
    assert main(["suite", "--suite", "nope", "controller=fixed_impedance"]) == 2
    assert "--suite: unknown suite 'nope'; allowed: changing_contact_v1" in capsys.readouterr().err
    full = tmp_path / "full"
    full.mkdir()
    (full / "keep.txt").write_text("mine")
    assert main(["suite", "--out", str(full), "controller=fixed_impedance"]) == 2
    assert "is not empty" in capsys.readouterr().err
    assert (full / "keep.txt").read_text() == "mine" and len(list(full.iterdir())) == 1


def test_results_do_not_depend_on_the_workers(tiny: Path, tmp_path: Path) -> None:
    """The same entry with one and with two worker processes: identical results.json."""
    a, b = tmp_path / "a", tmp_path / "b"
    assert _suite(tiny, a, "controller=fixed_impedance") == 0
    assert main(["suite", "--suite", str(tiny), "--out", str(b), "--jobs", "2",
                 "controller=fixed_impedance"]) == 0  # fmt: skip
    assert (a / "results.json").read_text() == (b / "results.json").read_text()


def test_stale_stored_results_are_left_out_with_a_warning(
    tiny: Path, tmp_path: Path, capsys
) -> None:  # noqa: ANN001
    """A stored entry whose fingerprint of a task differs (another scene) is not ranked
    there."""
    assert _suite(tiny, tmp_path / "regen", "--regenerate", "low") == 0
    path = results_dir(load_suite(str(tiny))) / "low.json"
    data = json.loads(path.read_text())
    data["fingerprints"]["smoke"] = "0" * 16
    path.write_text(json.dumps(data))
    capsys.readouterr()
    assert _suite(tiny, tmp_path / "mine", "controller=fixed_impedance_high") == 0
    assert "stored low on smoke is of another version of the task" in capsys.readouterr().err
    rows = list(csv.DictReader((tmp_path / "mine" / "leaderboard.csv").open()))
    assert {r["status"] for r in rows if r["entry"] == "low" and r["task"] == "smoke"} == {
        "missing"
    }


def test_shipped_results_are_of_todays_tasks() -> None:
    """Every stored built-in entry covers every task of the shipped suite, with the
    fingerprint today's configs give: a change to a task's scene or the protocol needs
    `ccm suite --regenerate` (or a new suite version) in the same commit."""
    suite = load_suite()
    stored = load_stored(suite)
    assert sorted(stored) == sorted(suite.entries)
    prints = precheck(suite, list(suite.tasks), ["controller=fixed_impedance"], [])
    assert task_fingerprints(suite, list(suite.tasks)) == prints  # the controller is not in it
    for entry, res in stored.items():
        assert res["fingerprints"] == prints, entry
        assert set(res["tasks"]) == set(suite.tasks), entry
        assert res["controller"] == list(suite.entries[entry])
    # the stored leaderboard is the board of the stored results (`ccm suite --board`)
    board = rank_entries(suite, stored, list(suite.tasks))
    assert (results_dir(suite) / "leaderboard.md").read_text() == markdown(board, None)

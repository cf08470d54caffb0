"""Learned state across trials and sessions (issue #5, point 4): the runner saves what each
condition's controller learned as JSON at the end of a run, and ``init_from=<run dir>`` starts
a run from it. The controllers' own round trips are in ``tests/test_controller_state.py``."""

from __future__ import annotations

import json
import os
import subprocess
import sys
from collections.abc import Callable, Sequence
from pathlib import Path

import pytest
from omegaconf import DictConfig

from ccm.core.errors import ConfigError
from ccm.experiment.components import plan_experiment, save_learned_states
from ccm.experiment.learned_state import STATE_FORMAT

Composer = Callable[[Sequence[str]], DictConfig]
CCM = str(Path(sys.executable).parent / "ccm")


# ----------------------------------------------------------------------------- runner


def plan_with(composer: Composer, init_from: Path | str, *overrides: str) -> list:
    """The runner's plan (what ``ccm run`` prechecks) with ``init_from``."""
    ov = ["experiment=single", "task=smoke", *overrides, f"init_from={init_from}"]
    return plan_experiment(composer(ov), lambda extra: composer([*ov, *extra]), 1)


def saved_run(composer: Composer, tmp_path: Path, controller: str = "avic") -> Path:
    """A run directory holding ``state/<controller>.json`` of a fresh controller."""
    ov = ["experiment=single", "task=smoke", f"controller={controller}"]
    plan = plan_experiment(composer(ov), lambda extra: composer([*ov, *extra]), 1)
    save_learned_states(tmp_path / "prev", plan, {controller: 5})
    return tmp_path / "prev"


def one_line_error(composer: Composer, init_from: Path | str, *overrides: str) -> str:
    with pytest.raises(ConfigError) as info:
        plan_with(composer, init_from, *overrides)
    assert info.value.key == "init_from"
    assert "\n" not in str(info.value)
    return str(info.value)


def test_runner_loads_the_condition_state(composer: Composer, tmp_path: Path) -> None:
    prev = saved_run(composer, tmp_path)
    record = json.loads((prev / "state" / "avic.json").read_text())
    assert {k: record[k] for k in ("format", "version", "controller_type", "condition")} == {
        "format": STATE_FORMAT, "version": 1, "controller_type": "avic", "condition": "avic"
    }  # fmt: skip
    ((cond, _),) = plan_with(composer, prev, "controller=avic")
    assert cond.prior_trials == 5  # the next save counts on from here
    # conditions whose controller does not learn need no file
    ((cond, _),) = plan_with(composer, prev, "controller=fixed_impedance")
    assert cond.prior_trials == 0


def test_runner_errors_name_init_from(composer: Composer, tmp_path: Path) -> None:
    prev = saved_run(composer, tmp_path, "avic_modes")
    msg = one_line_error(composer, tmp_path / "nope", "controller=avic")
    assert "is not a directory" in msg
    msg = one_line_error(composer, prev, "controller=avic")
    assert "no learned state for condition 'avic'" in msg and "found: avic_modes" in msg
    path = prev / "state" / "avic_modes.json"
    good = path.read_text()
    record = json.loads(good)
    (prev / "state" / "avic.json").write_text(json.dumps(record))  # another type's state
    msg = one_line_error(composer, prev, "controller=avic")
    assert "controller type 'avic_modes', this condition's is 'avic'" in msg
    for text, expected in [
        (good[: len(good) // 2], "not a readable JSON file"),
        ("[1, 2]", "format None is not 'ccm-learned-state'"),
        (json.dumps({**record, "version": 7}), "version 7, this ccm reads 1"),
        (json.dumps({**record, "state": {"modes": []}}), "invalid learned state"),
        (json.dumps({**record, "trials": -1}), "needs 'trials'"),
        (json.dumps({**record, "state": {**record["state"], "x": [[1.0, 1e300]]}}),
         "state.x[0][1] = 1e+300: a learned state holds finite numbers within ±1e+12"),
    ]:  # fmt: skip
        path.write_text(text)
        msg = one_line_error(composer, prev, "controller=avic_modes")
        assert msg.startswith(f"init_from: {path}: ") and expected in msg, msg
    path.unlink()  # issue #39: a directory or a FIFO in a state file's place was "no state"
    path.mkdir()
    msg = one_line_error(composer, prev, "controller=avic_modes")
    assert msg == f"init_from: {path}: is a directory, not a file"
    path.rmdir()
    os.mkfifo(path)  # reading it would block: refused without opening it
    msg = one_line_error(composer, prev, "controller=avic_modes")
    assert msg == f"init_from: {path}: is not a regular file (a FIFO, socket or device)"


# ----------------------------------------------------------------------------- ccm run


def ccm(args: list[str], cwd: Path) -> subprocess.CompletedProcess[str]:
    return subprocess.run(
        [CCM, *args], cwd=cwd, capture_output=True, text=True, timeout=120, check=False
    )


RUN = [
    "run",
    "experiment=single",
    "controller=avic_modes",
    "task=slide_surfaces_2d",
    "experiment.fast=true",
    "experiment.fast_time_s=3.5",
    "experiment.figures=false",
]  # fmt: skip  (3.5 s: approach, press and a first stretch of sliding)


def test_ccm_run_continues_from_a_previous_run(tmp_path: Path) -> None:
    res = ccm([*RUN, "hydra.run.dir=first"], tmp_path)
    assert res.returncode == 0, res.stderr
    res = ccm([*RUN, "hydra.run.dir=second", "init_from=first"], tmp_path)
    assert res.returncode == 0, res.stderr
    one, two = (
        json.loads((tmp_path / run / "state" / "avic_modes.json").read_text())
        for run in ("first", "second")
    )
    assert one["format"] == two["format"] == STATE_FORMAT
    assert (one["trials"], two["trials"]) == (1, 2)
    n1, n2 = one["state"]["classifier"]["modes"], two["state"]["classifier"]["modes"]
    assert len(n1) >= 1 and len(n2) == len(n1)  # the same surface: a known mode, not a new one
    assert n2[0]["count"] > n1[0]["count"]
    for m1, m2 in zip(one["state"]["modes"], two["state"]["modes"], strict=True):
        seen = (m1["forward_model"]["igmm"]["n_seen"], m2["forward_model"]["igmm"]["n_seen"])
        assert 0 < seen[0] < seen[1] and m1["samples"] < m2["samples"]  # not reset
    summary = json.loads((tmp_path / "second" / "summary.json").read_text())
    assert summary["status"] == "ok" and summary["init_from"] == "first"
    assert [t["trial"] for t in summary["trials"]] == [1]  # numbered within the run
    assert "init_from" not in json.loads((tmp_path / "first" / "summary.json").read_text())


def test_ccm_run_bad_init_from_is_one_line(tmp_path: Path) -> None:
    bad = tmp_path / "bad" / "state"
    bad.mkdir(parents=True)
    (bad / "avic.json").write_text('{"format": "ccm-learned-state", "vers')
    for value, expected in [("nope", "init_from: 'nope' is not a directory"), ("bad", "JSON")]:
        res = ccm(["run", "experiment=single", "controller=avic", f"init_from={value}"], tmp_path)
        assert res.returncode == 2
        lines = res.stderr.strip().splitlines()
        assert len(lines) == 1 and expected in lines[0] and "init_from" in lines[0], res.stderr
        assert "Traceback" not in res.stderr
    assert not list(tmp_path.rglob("summary.json"))

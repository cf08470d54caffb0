"""Oracle tests of the suite's per-trial metrics (``ccm.metrics.suite``) and of the ranking
rule of the leaderboard (``ccm.suite.board``): each case is built by hand so the expected
numbers follow from the definitions in the module docstrings."""

from __future__ import annotations

import numpy as np
import pytest

from ccm.metrics.suite import count_contact_losses, suite_metrics
from ccm.suite.board import rank_entries
from ccm.suite.definition import load_suite

DT = 0.001


def _log(n: int = 10) -> dict[str, np.ndarray]:
    t = np.arange(n) * DT
    z = np.zeros(n)
    return {"t": t, "n_contacts": z.copy(), **{f"{p}_{a}": z.copy() for p in
            ("contact_force", "cmd_force", "vel") for a in "xy"}}  # fmt: skip


def test_contact_force_peak_overshoot_and_losses() -> None:
    """Contact on steps 2-3 and 6-8: the 2-step gap is one loss at a 2 ms minimum (the last
    step's 1-step gap is none); force 3, 4 N then 5, 12, 5 N: peak 12 N, median in contact
    5 N, so the overshoot is 7 N."""
    log = _log()
    touch = [2, 3, 6, 7, 8]
    log["n_contacts"][touch] = 1
    log["contact_force_x"][touch] = [3.0, 4.0, 5.0, 12.0, 5.0]
    out = suite_metrics(log, 2, {"contact_loss_min_s": 0.002, "completion_time_s": None})
    assert out["peak_contact_force_N"] == 12.0
    assert out["force_overshoot_N"] == 7.0
    assert out["contact_losses"] == 1.0


def test_contact_losses_count_runs_of_the_minimum_length() -> None:
    """After the first contact, no-contact runs of at least min_s count, at the end too;
    before the first contact nothing counts; never in contact: None."""
    touching = np.array([0, 0, 1, 1, 0, 0, 1, 0, 0, 0], dtype=bool)
    assert count_contact_losses(touching, DT, 0.002) == 2.0  # steps 4-5 and 7-9
    assert count_contact_losses(touching, DT, 0.003) == 1.0  # only 7-9
    assert count_contact_losses(touching, DT, 0.004) == 0.0
    assert count_contact_losses(np.zeros(5, dtype=bool), DT, 0.002) is None


def test_effort_energy_and_censored_completion() -> None:
    """F_cmd = (3, 4) N throughout: effort = 5 N x 10 steps x 1 ms = 0.05 N s; v = (1, -1)
    m/s on the first 5 steps: |F.v| = 1 W there, energy 5 ms x 1 W = 0.005 J (the sign of
    the power does not matter). A trial that never completes is censored at its end
    (t[-1] + dt = 10 ms), one that does keeps its time."""
    log = _log()
    log["cmd_force_x"][:], log["cmd_force_y"][:] = 3.0, 4.0
    log["vel_x"][:5], log["vel_y"][:5] = 1.0, -1.0
    out = suite_metrics(log, 2, {"completion_time_s": None})
    assert out["effort_Ns"] == pytest.approx(0.05)
    assert out["energy_J"] == pytest.approx(0.005)
    assert out["time_to_complete_s"] == pytest.approx(0.010) and out["completed"] == 0.0
    assert out["peak_contact_force_N"] == 0.0 and out["force_overshoot_N"] is None
    done = suite_metrics(log, 2, {"completion_time_s": 0.004})
    assert done["time_to_complete_s"] == 0.004 and done["completed"] == 1.0


def _results(tasks: dict) -> dict:
    return {"tasks": {t: {"status": st, "error": None if st == "ok" else "boom",
                          "seeds": {str(i): {"rms_tracking_error_m": v, "effort_Ns": v}
                                    for i, v in enumerate(vals)}}
                      for t, (st, vals) in tasks.items()}}  # fmt: skip


def test_ranks_ties_failures_and_score() -> None:
    """On multi_spring (ranks tracking, time, effort, energy): a has mean 1, b mean 2, c the
    same as a (tie: both 1.5); d failed: last rank (4) in every ranked cell. The score is
    the mean rank over the cells an entry is ranked in (time and energy are missing here, so
    not ranked: two cells each)."""
    suite = load_suite()
    res = {
        "a": _results({"multi_spring": ("ok", [0.5, 1.5])}),
        "b": _results({"multi_spring": ("ok", [2.0, 2.0])}),
        "c": _results({"multi_spring": ("ok", [1.0, 1.0])}),
        "d": _results({"multi_spring": ("failed", [])}),
    }
    board = rank_entries(suite, res, ["multi_spring"])
    cell = board.cells[("a", "multi_spring", "rms_tracking_error_m")]
    assert cell.mean == 1.0 and cell.n == 2
    assert cell.half == pytest.approx(12.706 * np.std([0.5, 1.5], ddof=1) / np.sqrt(2))
    assert cell.rank == 1.5 and board.cells[("c", "multi_spring", "effort_Ns")].rank == 1.5
    assert board.cells[("b", "multi_spring", "rms_tracking_error_m")].rank == 3.0
    assert board.cells[("d", "multi_spring", "effort_Ns")].rank == 4.0
    assert board.cells[("a", "multi_spring", "energy_J")].rank is None
    assert board.score == {"a": 1.5, "b": 3.0, "c": 1.5, "d": 4.0}
    assert board.entries == ["a", "c", "b", "d"]
    assert board.status[("d", "multi_spring")] == "failed"


def test_equal_numbers_on_the_board_tie() -> None:
    """Means that agree to the 4 significant figures the board prints share a rank (109.6 N
    and 109.64 N); 109.7 N is behind them."""
    suite = load_suite()
    res = {e: _results({"multi_spring": ("ok", [v])})
           for e, v in (("a", 109.6), ("b", 109.64), ("c", 109.7))}  # fmt: skip
    board = rank_entries(suite, res, ["multi_spring"])
    ranks = [board.cells[(e, "multi_spring", "effort_Ns")].rank for e in "abc"]
    assert ranks == [1.5, 1.5, 3.0]

"""Oracle tests of seed B's trial metrics (``ccm.metrics.mpc.gp_mpc_metrics``; issue #39 item 1).

A synthetic 2-D log whose every quantity is known by construction: the first contact at
0.2 s with a 5 N force (3, 4) after 50 ms at 8 N, a 10 ms loss of contact at 0.5 s and a 3 ms
one at 0.7 s, a damping that depends on the distance to the human's shoulder, a belief that
reaches the true goal, and a tool that moves toward the human's goal. Each metric is checked
against the value its definition (the module docstring) gives.
"""

from __future__ import annotations

import numpy as np
import pytest

from ccm.metrics.mpc import gp_mpc_metrics

DT = 0.001
N = 1000


def _log() -> dict[str, np.ndarray]:
    t = np.arange(N) * DT
    touching = (t >= 0.2 - 1e-9).astype(float)
    touching[500:510] = 0.0  # a 10 ms loss (counted: >= 5 ms)
    touching[700:703] = 0.0  # a 3 ms one (not counted)
    fx, fy = np.zeros(N), np.zeros(N)
    fx[200:], fy[200:] = 3.0, 4.0  # |f| = 5 N from 0.2 s
    fx[200:250], fy[200:250] = 4.8, 6.4  # |f| = 8 N for the first 50 ms: out of the band
    far = t >= 0.6  # the tool is 1 m from the shoulder from 0.6 s, 0.2 m before
    pos_x = np.where(far, 1.0, 0.2)
    belief_1 = np.clip(0.5 + t, 0.0, 1.0)  # 0.9 at t = 0.4 s
    return {
        "t": t, "n_contacts": touching, "contact_force_x": fx, "contact_force_y": fy,
        "vel_x": np.zeros(N), "vel_y": np.zeros(N), "pos_x": pos_x, "pos_y": np.zeros(N),
        "damping_x_Nspm": np.where(far, 500.0, 100.0), "damping_y_Nspm": np.full(N, 150.0),
        "belief_0": 1.0 - belief_1, "belief_1": belief_1, "truth_human_goal": np.ones(N),
        "truth_human_goal_x_m": np.full(N, 2.0), "truth_human_goal_y_m": np.zeros(N),
        "f_ref_x_N": np.full(N, -3.0), "f_ref_y_N": np.full(N, 7.0),
    }  # fmt: skip


PARAMS = {
    "press_force_N": 5.0, "press_tol_N": 1.5, "press_hold_s": 0.1,
    "human_shoulder": [0.0, 0.0, 0.0], "far_from_human_m": 0.5,
    "varied_axis": "x", "repeatable_axis": "y", "belief_level": 0.9,
    "controller_report": {"mpc_solves": 7, "mpc_infeasible": 2, "disturbance_alpha": 1.5},
}  # fmt: skip


def test_seed_b_trial_metrics_give_their_definitions_values() -> None:
    m = gp_mpc_metrics(_log(), 2, PARAMS)
    assert m["peak_force_N"] == pytest.approx(8.0) and m["contact_made"] == 1.0
    assert m["first_contact_s"] == pytest.approx(0.2)
    assert m["contact_losses"] == 1.0  # 10 ms counts, 3 ms does not (contact_loss_min_s 5 ms)
    # the force first stays within 5 ± 1.5 N for press_hold_s from 0.25 s on
    assert m["press_settle_time_s"] == pytest.approx(0.25)
    assert (m["mpc_solves"], m["mpc_infeasible"], m["disturbance_alpha_N"]) == (7.0, 2.0, 1.5)
    assert m["rms_vel_low_mps"] == 0.0 and m["rms_vel_high_mps"] == 0.0
    assert m["mean_damping_x_Nspm"] == pytest.approx(0.4 * 500 + 0.6 * 100)
    assert m["mean_damping_y_Nspm"] == pytest.approx(150.0)
    # far from the human (>= 0.5 m): 40 % of the samples, damping (500 + 150) / 2 there
    assert m["far_from_human_frac"] == pytest.approx(0.4)
    assert m["mean_damping_far_Nspm"] == pytest.approx(325.0)
    assert m["damping_ratio_varied_repeatable"] == pytest.approx(260.0 / 150.0)
    assert m["belief_correct_final"] == 1.0 and m["time_to_belief_s"] == pytest.approx(0.4)
    # the goal (2, 0): 1.8 m away at the start, 1.0 m at the end; ĝ = (1, 0), −f_ref·ĝ = 3 N
    assert m["goal_approach_m"] == pytest.approx(0.8)
    assert m["f_ref_toward_goal_N"] == pytest.approx(3.0)


def test_without_contact_or_settling_the_contact_metrics_are_none() -> None:
    """No contact: None for the contact metrics (not 0); a force that never settles: None."""
    log = _log()
    log["n_contacts"] = np.zeros(N)
    m = gp_mpc_metrics(log, 2, PARAMS)
    assert m["contact_made"] == 0.0 and m["first_contact_s"] is None
    assert m["contact_losses"] is None and m["press_settle_time_s"] is None
    log = _log()
    log["contact_force_x"] = np.where(log["t"] >= 0.2, 9.0, 0.0)
    assert gp_mpc_metrics(log, 2, PARAMS)["press_settle_time_s"] is None
    near = _log()
    near["pos_x"] = np.full(N, 0.2)
    m = gp_mpc_metrics(near, 2, PARAMS)
    assert m["far_from_human_frac"] == 0.0 and m["mean_damping_far_Nspm"] is None

"""GP-MPC (seed B Eq. 13-20): problem structure, constraints, infeasibility handling, and the
stochastic propagation (Eq. 7-8) against Monte Carlo."""

from __future__ import annotations

import json
import math
from functools import partial
from typing import Any

import numpy as np
import pytest

from ccm.control.mpc.admittance import rollout, system_matrices
from ccm.control.mpc.gp_mpc import GPMPC
from ccm.control.mpc.problem import GPMPCProblem, _ipopt_options
from ccm.control.mpc.settings import MPCSettings, Weights
from ccm.core.errors import ConfigError
from ccm.core.types import Observation, TargetSample
from ccm.learn.gp.gp_force_models import GPForceModels
from tests.mpc_cases import wall
from tests.refusals import refusal

K_WALL = 45000.0  # N/m, seed B's medium environment


def _contact_data(n: int, rng: np.random.Generator, wall: float = 0.0, pts: int = 30):
    """Synthetic demonstration: a push along x into a hinge-shaped wall at ``wall``."""
    X = rng.uniform(-0.05, 0.05, (pts, n))
    n_in = pts // 3  # a third of the samples pressed up to 0.8 mm (36 N) into the wall
    X[:, 0] = np.r_[np.linspace(-0.08, wall, pts - n_in), np.linspace(wall, wall + 8e-4, n_in)]
    F = rng.normal(0.0, 0.2, (pts, n))
    F[:, 0] += -K_WALL * np.maximum(0.0, X[:, 0] - wall)
    return X, F


@pytest.fixture(scope="module")
def gp2() -> GPForceModels:
    X, F = _contact_data(2, np.random.default_rng(0))
    return GPForceModels(2, mean="hinge", hinge_form="smooth", n_restarts=1).fit(X, F)


def _problem(gp: GPForceModels, **kw) -> GPMPCProblem:
    w = Weights(vel=1.0, f_ref_target=1.0, delta_mass=1e-3, delta_damping=1e-6)
    return GPMPCProblem(
        [gp.casadi_functions()], 2, horizon=6, ts=0.01, f_ref_target=[-15.0, 0.0], weights=w, **kw
    )


def _state(x: float = -0.03, v: float = 0.05) -> np.ndarray:
    return np.array([x, 0.0, v, 0.0])


M0, D0, FR0 = np.full(2, 5.0), np.full(2, 500.0), np.zeros(2)


def test_solution_obeys_dynamics_bounds_and_rate_limits(gp2: GPForceModels) -> None:
    prob = _problem(gp2)
    sol = prob.solve(_state(), [1.0], M0, D0, FR0)
    assert sol.success, sol.status
    # rate limits and bounds
    assert np.all(np.abs(sol.f_ref - FR0) <= prob.f_ref_rate_max + 1e-6)
    assert np.all(np.abs(sol.mass - M0) <= prob.delta_mass_max + 1e-6)
    assert np.all(sol.mass >= prob.mass_bounds[0] - 1e-6)
    assert np.all(sol.damping >= prob.damping_bounds[0] - 1e-6)

    # the first predicted state follows Eq. 7 from the measured state (multiple shooting)
    def force(x: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        return gp2.predict(np.asarray(x)[None, :])[0][0], np.zeros(2)

    mus, _ = rollout(sol.mass, sol.damping, 0.01, _state(), np.zeros((4, 4)), sol.f_ref, force, 1)
    np.testing.assert_allclose(sol.predicted[0, 1], mus[1], atol=1e-6)
    # the f^r target cost pulls f^r toward -15 N along x
    assert sol.f_ref[0] < -1.0


def test_well_damped_constraint_holds_on_the_horizon(gp2: GPForceModels) -> None:
    prob = _problem(gp2, well_damped={"zeta": 1.2}, delta_damping_max=5000.0)
    sol = prob.solve(_state(x=-0.004, v=0.1), [1.0], M0, D0, FR0)
    assert sol.success, sol.status
    for row in sol.predicted[0, 1:]:
        k_e = -np.diag(np.array([m.mean_gradient(row[:2]) for m in gp2.models]))
        need = 2 * 1.2 * np.sqrt(sol.mass * np.maximum(k_e, 0.0))
        assert np.all(sol.damping >= need - 1e-3)
    # entering the wall needs D >= 2 zeta sqrt(M K) = 1138 N s/m at M = 5 kg: the constrained
    # plan raises D and holds back (seed B §6.1: it "paused to allow the damping to increase")
    free = _problem(gp2, delta_damping_max=5000.0).solve(_state(-0.004, 0.1), [1.0], M0, D0, FR0)
    assert free.success
    assert sol.damping[0] > free.damping[0] + 50.0
    assert sol.predicted[0, -1, 0] < free.predicted[0, -1, 0]


def test_infeasible_solve_keeps_last_command_and_is_counted(gp2: GPForceModels) -> None:
    """Issue #7: a solve that comes back infeasible is not applied and is counted."""
    ctrl = GPMPC(
        mass_kg=10.0, demo_modes=[0], max_points=30, gp={"mean": "hinge", "n_restarts": 0},
        mpc={"horizon": 4, "ts": 0.01,
             # a force bound below the GP's own noise margin: no trajectory can satisfy it
             "chance": {"f_max": 1e-3, "epsilon": 0.01}},
        mpc_period_s=0.01, init_f_ref=[-3.0, 0.0],
    )  # fmt: skip
    target = _demonstrate(ctrl)  # fits the GPs and builds Eq. 13
    for k in range(30):
        ctrl.step(_obs(k * 0.001, np.array([-0.02, 0.0]), np.zeros(2)), target)
    rep = ctrl.report()
    assert rep["mpc_solves"] == 3 and rep["mpc_infeasible"] == 3
    np.testing.assert_array_equal(ctrl.f_ref, [-3.0, 0.0])  # the last feasible command
    np.testing.assert_array_equal(ctrl.damping, [500.0, 500.0])
    assert ctrl.signals()["mpc_infeasible"] == 3.0


def _demonstrate(ctrl: GPMPC) -> TargetSample:
    """Feed one demonstration (the synthetic contact data at 100 Hz), end it (the GPs are fitted
    and Eq. 13 built) and start the first execution trial; returns the target to step with."""
    X, F = _contact_data(2, np.random.default_rng(1))
    ctrl.reset(2, 0.001)
    target = TargetSample(0.0, np.zeros(2), np.zeros(2), np.zeros(2), np.zeros(1))
    for i, (x, f) in enumerate(zip(X, F, strict=True)):
        for _ in range(ctrl.record_every):
            ctrl.step(_obs(i * 0.01, x, f), target)
    ctrl.end_trial()
    ctrl.reset(2, 0.001)
    return target


def _obs(t: float, x: np.ndarray, f: np.ndarray) -> Observation:
    z = np.zeros(2)
    return Observation(t, np.asarray(x, float), np.zeros(1), z, np.zeros(1), np.asarray(f), z[:1])


def test_belief_weights_the_modes(gp2: GPForceModels) -> None:
    X, F = _contact_data(2, np.random.default_rng(2))
    F[:, 1] += 8.0  # mode 1: a human pushing +y as well
    gp_b = GPForceModels(2, mean="zero", n_restarts=0).fit(X, F)
    w = Weights(vel=1.0, force=1.0, f_ref=1e-3)
    prob = GPMPCProblem([gp2.casadi_functions(), gp_b.casadi_functions()], 2, horizon=5,
                        ts=0.01, weights=w)  # fmt: skip
    a = prob.solve(_state(), [1.0, 0.0], M0, D0, FR0)
    prob.reset_warm_start()
    b = prob.solve(_state(), [0.0, 1.0], M0, D0, FR0)
    assert a.success and b.success
    assert abs(a.f_ref[1] - b.f_ref[1]) > 0.1  # the plan follows the believed mode


def test_warm_start_cuts_iterations(gp2: GPForceModels) -> None:
    prob = _problem(gp2)
    cold = prob.solve(_state(), [1.0], M0, D0, FR0)
    warm = prob.solve(_state(), [1.0], M0, D0, FR0)
    assert warm.iterations < cold.iterations


def test_propagation_matches_monte_carlo() -> None:
    """Eq. 7-8 against 20000 sampled trajectories, for a force model whose mean and variance
    do not depend on pose (where Eq. 7-8 are exact): within 5 % (issue #7)."""
    rng = np.random.default_rng(0)
    m, d, ts, steps = np.array([5.0, 8.0]), np.array([500.0, 300.0]), 0.01, 10
    f_mu, f_var = np.array([4.0, -2.0]), np.array([9.0, 1.0])
    mus, sigmas = rollout(m, d, ts, np.zeros(4), np.zeros((4, 4)), np.zeros(2),
                          lambda x: (f_mu, f_var), steps)  # fmt: skip
    from ccm.control.mpc.admittance import system_matrices

    a, b = system_matrices(m, d, ts)
    xi = np.zeros((20000, 4))
    for _ in range(steps):
        f = f_mu + rng.normal(size=(20000, 2)) * np.sqrt(f_var)
        xi = xi @ a.T + f @ b.T
    np.testing.assert_allclose(xi.mean(axis=0), mus[-1], rtol=0.05)
    np.testing.assert_allclose(np.diag(np.cov(xi.T)), np.diag(sigmas[-1]), rtol=0.05)


def test_propagation_matches_monte_carlo_with_a_pose_dependent_force() -> None:
    """A human-like force field μ_f(x) = k (g − x) (200 N/m): Eq. 7-8 evaluate it at the mean
    and ignore the slope's effect on Σ; over 10 steps of 10 ms that stays within 5 % of
    20000 sampled trajectories whose force is drawn at their own pose."""
    rng = np.random.default_rng(1)
    m, d, ts, steps, k, g = np.full(2, 5.0), np.full(2, 500.0), 0.01, 10, 200.0, 0.1
    var = np.array([4.0, 4.0])

    def field(x: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        return k * (g - np.asarray(x)), var

    mus, sigmas = rollout(m, d, ts, np.zeros(4), np.zeros((4, 4)), np.zeros(2), field, steps)
    from ccm.control.mpc.admittance import system_matrices

    a, b = system_matrices(m, d, ts)
    xi = np.zeros((20000, 4))
    for _ in range(steps):
        f = k * (g - xi[:, :2]) + rng.normal(size=(20000, 2)) * np.sqrt(var)
        xi = xi @ a.T + f @ b.T
    np.testing.assert_allclose(xi.mean(axis=0), mus[-1], rtol=0.05)
    np.testing.assert_allclose(np.diag(np.cov(xi.T)), np.diag(sigmas[-1]), rtol=0.05)


@pytest.mark.parametrize(
    ("kwargs", "key"),
    [
        ({"horizon": 0}, "controller.mpc.horizon"),
        ({"ts": -0.01}, "controller.mpc.ts"),
        ({"mass_bounds": [0.0, 10.0]}, "controller.mpc.mass_bounds"),
        ({"well_damped": {"zeta": float("nan")}}, "controller.mpc.well_damped.zeta"),
        ({"well_damped": {"stiffness": "magic"}}, "controller.mpc.well_damped.stiffness"),
        ({"chance": {"f_max": -1.0}}, "controller.mpc.chance.f_max"),
    ],
)
def test_bad_settings_name_the_key(gp2: GPForceModels, kwargs: dict, key: str) -> None:
    with pytest.raises(ConfigError) as err:
        GPMPCProblem([gp2.casadi_functions()], 2, **kwargs)
    assert key in str(err.value)


def test_force_delay_shifts_the_admittance_response() -> None:
    """force_delay_s: a force step reaches the admittance reference exactly that late."""
    target = TargetSample(0.0, np.zeros(2), np.zeros(2), np.zeros(2), np.zeros(1))
    responses = []
    for delay in (0.0, 0.003):
        ctrl = GPMPC(mpc=False, mass_kg=10.0, force_delay_s=delay)
        ctrl.reset(2, 0.001)
        v = []
        for k in range(8):
            f = np.array([10.0, 0.0]) if k >= 2 else np.zeros(2)
            ctrl.step(_obs(k * 0.001, np.zeros(2), f), target)
            v.append(ctrl._v_ref[0])
        responses.append(np.flatnonzero(np.array(v) > 0)[0])
    assert responses == [2, 5]


@pytest.mark.parametrize(
    ("mpc", "key"),
    [
        ({"weights": {"nope": 1.0}}, "controller.mpc.weights.nope"),
        ({"weights": {"vel": -1.0}}, "controller.mpc.weights.vel"),
        ({"chance": {"fmax": 1.0}}, "controller.mpc.chance.fmax"),
        ({"chance": {"epsilon": 1.5}}, "controller.mpc.chance.epsilon"),
        ({"chance": {"quantile": "erf"}}, "controller.mpc.chance.quantile"),
        ({"disturbance": {"alpha": 1.0, "beta": 2.0}}, "controller.mpc.disturbance.beta"),
        ({"horizons": 5}, "controller.mpc.horizons"),
    ],
)
def test_controller_checks_mpc_settings_at_construction(mpc: dict, key: str) -> None:
    """Bad MPC settings fail when the controller is built, not after the demonstrations."""
    with pytest.raises(ConfigError) as err:
        GPMPC(mpc=mpc)
    assert key in str(err.value)


def test_the_controller_records_the_sigma_f_its_solve_saw(gp2: GPForceModels) -> None:
    """Issue #37: each run records Σ^f at the plan's last point ξ_{t+H} (where Eq. 18 is
    imposed), as the GP gives it there, times gp_var_scale."""
    ctrl = GPMPC(
        mass_kg=10.0, demo_modes=[0], max_points=30,
        gp={"mean": "hinge", "n_restarts": 0, "variance": "tied",
            "length_scale_bounds": [2e-3, 1e-2]},  # short: Σ^f varies along the plan
        mpc={"horizon": 4, "ts": 0.01, "gp_var_scale": 3.0}, mpc_period_s=0.01,
    )  # fmt: skip
    target = _demonstrate(ctrl)  # fits the GPs and builds Eq. 13
    assert np.all(np.isnan(ctrl.signals()["sigma_f_x_N2"]))  # no solve yet
    seen = []
    solve = ctrl._problem.solve
    ctrl._problem.solve = lambda *a: seen.append(solve(*a)) or seen[-1]
    moving = Observation(0.0, np.array([-0.01, 0.0]), np.zeros(1), np.array([0.3, 0.0]),
                         np.zeros(1), np.zeros(2), np.zeros(1))  # fmt: skip
    ctrl.step(moving, target)
    last = seen[-1].predicted[0, -1, :2]
    assert last[0] > -0.01 + 2e-3  # 0.3 m/s, braked by D / M = 100 /s over the horizon
    expected = 3.0 * ctrl.models[0].predict(last[None, :])[1][0]
    sig = ctrl.signals()
    np.testing.assert_allclose([sig["sigma_f_x_N2"], sig["sigma_f_y_N2"]], expected, rtol=1e-12)
    start = 3.0 * ctrl.models[0].predict(np.array([[-0.01, 0.0]]))[1][0]
    assert not np.allclose(expected, start)  # the plan's end, not the measured pose


def test_the_inner_loop_renders_eq4_and_tracks_it_with_pd() -> None:
    """Between MPC solves (seed B Eq. 4, backward Euler): (M + dt D) v⁺ = M v + dt (f − f^r),
    x⁺ = x + dt v⁺, and the command m a_ref + k_p (x_ref − x) + k_d (v_ref − v); the 2-D
    tool's angle is held by k_rot (θ₀ − θ) − d_rot ω. Every term is non-zero here."""
    ctrl = GPMPC(mpc=False, mass_kg=2.0, inner_kp=300.0, inner_kd=40.0, rot_stiffness=5.0,
                 rot_damping=0.5, init_f_ref=[1.5, -0.5])  # fmt: skip
    ctrl.reset(2, 0.001)
    np.testing.assert_array_equal(ctrl.f_ref, [1.5, -0.5])
    target = TargetSample(0.0, np.zeros(2), np.zeros(2), np.zeros(2), np.zeros(1))
    z = np.zeros(2)
    ctrl.step(Observation(0.0, z, np.array([0.2]), z, np.zeros(1), z, z[:1]), target)
    m, d, fr, v0, x0 = ctrl.mass, ctrl.damping, ctrl.f_ref, ctrl._v_ref, ctrl._x_ref
    f, x, v = np.array([6.0, -2.0]), np.array([0.001, -0.002]), np.array([0.05, 0.01])
    o = Observation(0.001, x, np.array([0.3]), v, np.array([0.4]), f, z[:1])
    cmd = ctrl.step(o, target)
    v_new = (m * v0 + 0.001 * (f - fr)) / (m + 0.001 * d)
    x_new = x0 + 0.001 * v_new
    expected = 2.0 * (v_new - v0) / 0.001 + 300.0 * (x_new - x) + 40.0 * (v_new - v)
    np.testing.assert_allclose(cmd.force, expected, rtol=1e-12)
    np.testing.assert_allclose(cmd.torque, [-5.0 * (0.3 - 0.2) - 0.5 * 0.4], rtol=1e-12)


def test_mpc_block_must_be_settings_or_false_and_report_starts_at_zero() -> None:
    with pytest.raises(ConfigError) as err:
        GPMPC(mpc=3)
    assert str(err.value) == "controller.mpc: must be a mapping of MPC settings or false"
    report = GPMPC(mpc=False).report()  # before any trial: nothing solved
    assert (report["mpc_solves"], report["mpc_infeasible"]) == (0, 0)


def test_config_ipopt_entries_reach_the_solver_options() -> None:
    opts = _ipopt_options({"max_iter": 7, "tol": 1e-9})
    assert (opts["ipopt.max_iter"], opts["ipopt.tol"]) == (7, 1e-9)
    assert opts["ipopt.warm_start_init_point"] == "yes"  # the defaults stay


def test_demonstrations_run_at_the_demonstration_impedance() -> None:
    """A demonstration trial uses demo_mass / demo_damping / demo_f_ref (seed B §5: the human
    leads the robot at a fixed admittance); a trial without an MPC uses the init_ values."""
    demo = GPMPC(demo_modes=[0], demo_mass=7.0, demo_damping=300.0, demo_f_ref=[2.0, -1.0])
    demo.reset(2, 0.001)
    assert demo.demonstrating
    np.testing.assert_array_equal(np.concatenate([demo.mass, demo.damping, demo.f_ref]),
                                  [7.0, 7.0, 300.0, 300.0, 2.0, -1.0])  # fmt: skip


def test_controller_refusals_are_whole_lines() -> None:
    line = partial(refusal, ConfigError)
    assert line(GPMPC, demo_modes=[]) == (
        "controller.demo_modes: needs at least one demonstration for the GPs"
    )
    assert line(GPMPC(mpc=False, init_mass=[1.0, 2.0, 3.0]).reset, 2, 0.001) == (
        "controller.init_mass: needs 1 or 2 values, got [1.0, 2.0, 3.0]"
    )
    key = "controller.mpc"
    assert line(MPCSettings.parse, {"chance": 3}, key) == (
        "controller.mpc.chance: must be a mapping with keys f_max, epsilon, quantile"
    )
    assert line(MPCSettings.parse, {"f_ref_target": [float("nan"), 0.0]}, key) == (
        "controller.mpc.f_ref_target: must be finite, got [nan, 0.0]"
    )
    wd = {"well_damped": {"stiffness": "fixed", "fixed_stiffness": -1.0}}
    assert line(MPCSettings.parse, wd, key) == (
        "controller.mpc.well_damped.fixed_stiffness: must be > 0, got -1.0"
    )
    assert line(MPCSettings.parse, {"disturbance": {"omega_p": 0.0}}, key) == (
        "controller.mpc.disturbance.omega_p: must be > 0, got 0.0"
    )


def test_mpc_settings_read_their_keys() -> None:
    wd = {"stiffness": "fixed", "fixed_stiffness": 900.0}
    st = MPCSettings.parse({"damping_bounds": [100.0, 200.0], "well_damped": wd}, "mpc")
    assert tuple(st.damping_bounds) == (100.0, 200.0)
    assert st.well_damped == (1.2, 900.0)  # ζ = 1.2 by default (seed B §6.1)
    ctrl = GPMPC(mpc={"disturbance": {"alpha": "demonstrations"}})
    assert ctrl._split_hz == pytest.approx(15.0)  # noqa: SLF001 - ω_p = 2π · 15 rad/s


def test_the_reference_force_ramps_at_its_rate_limit_over_the_horizon(gp2: GPForceModels) -> None:
    """Eq. 13's rate limit |f^r_k − f^r_{k−1}| ≤ 10 N per MPC step, from f^r_prev = 25 N to
    the −15 N target: 15, 5, −5, then −15 N. The plan's f^r_k is read back from its predicted
    states through Eq. 7, μ_{k+1} = A μ_k + B (μ^f(μ_k) − f^r_k), with the solved M, D."""
    prob = _problem(gp2)
    sol = prob.solve(_state(), [1.0], M0, D0, np.array([25.0, 0.0]))
    assert sol.success, sol.status
    a, b = (np.asarray(m) for m in system_matrices(sol.mass, sol.damping, 0.01))
    mus = sol.predicted[0]
    f_ref = [
        gp2.predict(mus[k][None, :2])[0][0] - np.linalg.lstsq(b, mus[k + 1] - a @ mus[k])[0]
        for k in range(prob.horizon)
    ]
    np.testing.assert_allclose(np.array(f_ref)[:, 0], [15.0, 5.0, -5.0, -15.0, -15.0, -15.0],
                               atol=1e-3)  # fmt: skip


def _small_gp_mpc(**kw: Any) -> GPMPC:
    """A GP-MPC with a short horizon and a quick GP fit; ``kw`` overrides its settings."""
    settings = {"mass_kg": 10.0, "demo_modes": [0], "max_points": 30,
                "gp": {"mean": "hinge", "n_restarts": 0}, "mpc": {"horizon": 4, "ts": 0.01},
                "mpc_period_s": 0.01}  # fmt: skip
    return GPMPC(**{**settings, **kw})


def test_learned_state_refits_the_same_gps_and_plans_the_same() -> None:
    """The demonstrations travel as JSON; a fresh controller refits its GPs from them at its
    next reset and then plans what the demonstrated one plans. A state with the wrong number
    of modes, or without its data, is refused on one line naming the key."""
    ctrl = _small_gp_mpc()
    target = _demonstrate(ctrl)
    state = json.loads(json.dumps(ctrl.state_dict(), allow_nan=False))
    assert state["trials_done"] == 1 and len(state["data"]) == 1 and len(state["data"][0]) > 0
    fresh = _small_gp_mpc()
    fresh.load_state_dict(state)
    assert fresh.state_dict() == state
    fresh.reset(2, 0.001)
    for c in (ctrl, fresh):
        for k in range(12):
            c.step(_obs(k * 0.001, np.array([-0.02, 0.0]), np.zeros(2)), target)
    assert fresh.report()["mpc_solves"] == ctrl.report()["mpc_solves"] > 0
    np.testing.assert_allclose(fresh.f_ref, ctrl.f_ref, atol=1e-9)
    np.testing.assert_allclose(fresh.damping, ctrl.damping, atol=1e-9)
    line = partial(refusal, ConfigError)
    assert line(_small_gp_mpc().load_state_dict, {**state, "data": []}) == (
        "controller.learned_state: has 0 modes, expected 1"
    )
    assert line(_small_gp_mpc().load_state_dict, {"trials_done": 1}) == (
        "controller.learned_state: malformed: 'data'"
    )


def test_the_controller_updates_its_belief_from_the_force_measured_at_the_pose() -> None:
    """Two demonstrations, one per mode (mode 1: the same wall and a human pushing +8 N
    along y). Executing, each solve first applies Eq. 12 to the force measured at the
    measured pose, with each mode's GP mean and variance there plus its noise: the belief is
    that Bayes update of the previous one, and a +8 N push moves it to mode 1."""
    from ccm.control.mpc.terms import belief_update

    ctrl = _small_gp_mpc(demo_modes=[0, 1], min_belief=0.01)
    X, F = _contact_data(2, np.random.default_rng(1))
    ctrl.reset(2, 0.001)
    target = TargetSample(0.0, np.zeros(2), np.zeros(2), np.zeros(2), np.zeros(1))
    for push in (0.0, 8.0):
        for i, (x, f) in enumerate(zip(X, F + [0.0, push], strict=True)):
            for _ in range(ctrl.record_every):
                ctrl.step(_obs(i * 0.01, x, f), target)
        ctrl.end_trial()
        ctrl.reset(2, 0.001)
    pose, force = np.array([-0.03, 0.01]), np.array([0.1, 8.2])
    expected = np.full(2, 0.5)
    for k in range(25):
        before = ctrl.solves
        ctrl.step(_obs(k * 0.001, pose, force), target)
        if ctrl.solves > before:
            preds = [g.predict(pose[None, :]) for g in ctrl.models]
            noise = np.array([[gm.noise_var_ for gm in g.models] for g in ctrl.models])
            expected = belief_update(expected, force, np.array([p[0][0] for p in preds]),
                                     np.array([p[1][0] for p in preds]) + noise,
                                     min_belief=0.01)  # fmt: skip
    assert ctrl.solves >= 2
    np.testing.assert_allclose(ctrl.belief, expected, rtol=1e-12)
    assert ctrl.belief[1] > 0.95
    sig = ctrl.signals()
    assert (sig["belief_0"], sig["belief_1"]) == tuple(ctrl.belief.tolist())
    assert sig["demonstration"] == 0.0 and sig["mpc_infeasible"] == 0.0


def test_each_mode_is_fit_on_max_points_spread_over_its_demonstration() -> None:
    """Seed B §3.1.1's GP per mode, fit on ``max_points`` rows spread evenly over the
    demonstration, its first and last row included: the same predictions as a GP fit by hand
    on those rows."""
    from ccm.learn.gp.gp_force_models import GPForceModels

    ctrl = _small_gp_mpc(max_points=10)
    _demonstrate(ctrl)
    X, F = _contact_data(2, np.random.default_rng(1))  # what _demonstrate fed, 30 rows
    (rows,) = ctrl.state_dict()["data"]
    np.testing.assert_array_equal(np.asarray(rows), np.hstack([X, F]))
    idx = np.round(np.linspace(0, 29, 10)).astype(int)
    assert idx[0] == 0 and idx[-1] == 29
    by_hand = GPForceModels(2, mean="hinge", n_restarts=0).fit(X[idx], F[idx])
    probe = np.array([[-0.05, 0.0], [0.0, 0.01], [4e-4, -0.02]])
    for got, want in zip(ctrl.models[0].predict(probe), by_hand.predict(probe), strict=True):
        np.testing.assert_allclose(got, want, rtol=1e-9, atol=1e-12)


def test_the_disturbance_and_arm_terms_are_on_exactly_when_their_weight_is() -> None:
    """Eq. 16-17 enter with any positive weight (here 0.5) and not at 0; Eq. 15's arm is
    built when its weight is positive or its block is given, not for weight 0 alone."""
    two_pi_15 = 2 * math.pi * 15
    half = MPCSettings.parse({"weights": {"disturbance": 0.5}}, "mpc")
    assert half.disturbance == (1.0, pytest.approx(two_pi_15))
    assert MPCSettings.parse({"weights": {"disturbance": 0.0}}, "mpc").disturbance is None
    assert MPCSettings.parse({"weights": {"joint_torque": 0.0}}, "mpc").joint_torque is None
    arm = MPCSettings.parse({"weights": {"joint_torque": 0.0},
                             "joint_torque": {"velocity": "predicted"}}, "mpc")  # fmt: skip
    assert arm.joint_torque is not None and arm.joint_torque.velocity == "predicted"
    assert MPCSettings.parse({"weights": {"joint_torque": 0.2}}, "mpc").joint_torque.l2 == 0.35


def test_impedance_steps_stay_inside_their_rate_limits_and_bounds(gp2: GPForceModels) -> None:
    """Eq. 13's bounds on one solve's variables: |f^r| ≤ f_ref_max; ΔM within ±5 kg and
    ΔD within ±500 N s/m (the rate limits), cut so that M ∈ [5, 60] kg and D ∈ [500, 5000]
    N s/m afterwards; near each end the bound is the distance left to it."""
    prob = _problem(gp2)
    n, h = 2, prob.horizon
    lo, hi = prob.bounds(np.array([58.0, 6.0]), np.array([4800.0, 700.0]))
    np.testing.assert_array_equal(lo[: n * h], -30.0)
    np.testing.assert_array_equal(hi[: n * h], 30.0)
    s = n * h
    np.testing.assert_array_equal(lo[s : s + 4], [-5.0, -1.0, -500.0, -200.0])
    np.testing.assert_array_equal(hi[s : s + 4], [2.0, 5.0, 200.0, 500.0])
    assert np.all(np.isinf(lo[s + 4 :])) and np.all(np.isinf(hi[s + 4 :]))  # the states


def _wall_functions() -> list:
    return [wall().casadi_functions()]


REFUSALS = [
    (lambda: GPMPC(mass_kg=-1.0), "controller.mass_kg: must be > 0, got -1.0"),
    (lambda: GPMPC(inner_kp=0.0), "controller.inner_kp: must be > 0, got 0.0"),
    (lambda: GPMPC(inner_kd=-1.0), "controller.inner_kd: must be >= 0, got -1.0"),
    (lambda: GPMPC(rot_stiffness=-1.0), "controller.rot_stiffness: must be >= 0, got -1.0"),
    (lambda: GPMPC(rot_damping=-2.0), "controller.rot_damping: must be >= 0, got -2.0"),
    (lambda: GPMPC(mpc_period_s=0.0), "controller.mpc_period_s: must be > 0, got 0.0"),
    (lambda: GPMPC(record_every=0), "controller.record_every: must be > 0, got 0"),
    (lambda: GPMPC(max_points=0), "controller.max_points: must be > 0, got 0"),
    (lambda: GPMPC(min_belief=-0.1), "controller.min_belief: must be >= 0, got -0.1"),
    (lambda: GPMPC(force_delay_s=-0.01), "controller.force_delay_s: must be >= 0, got -0.01"),
    (lambda: GPMPC(demo_modes=[0, 2]),
     "controller.demo_modes: labels must be 0..N-1, each used; got [0, 2]"),
    (lambda: GPMPC(mpc={"horizon": 0}), "controller.mpc.horizon: must be an integer >= 1, got 0"),
    (lambda: GPMPC(mpc=False, init_damping=[-5.0, 1.0]).reset(2, 0.001),
     "controller.init_damping: must be >= 0, got [-5.0, 1.0]"),
    (lambda: GPMPC(mpc=False, init_mass=[0.0, 1.0]).reset(2, 0.001),
     "controller.init_mass: must be > 0, got [0.0, 1.0]"),
    (lambda: GPMPC(demo_mass=-3.0).reset(2, 0.001),
     "controller.demo_mass: must be > 0, got [-3.0, -3.0]"),
    (lambda: system_matrices([1.0, 2.0], [1.0], 0.01),
     "admittance.damping: needs the shape of mass (2,)"),
    (lambda: system_matrices([-1.0], [1.0], 0.01),
     "admittance.mass: must be finite and > 0, got [-1.0]"),
    (lambda: system_matrices([1.0], [-1.0], 0.01),
     "admittance.damping: must be finite and >= 0, got [-1.0]"),
    (lambda: GPMPCProblem([], 1), "controller.mpc.modes: needs at least one mode's GP models"),
    (lambda: GPMPCProblem(_wall_functions(), 0),
     "controller.mpc.n: must be an integer >= 1, got 0"),
    (lambda: GPMPCProblem(_wall_functions(), 1, disturbance={"alpha": "demonstrations"},
                          weights={"disturbance": 1.0}),
     "controller.mpc.disturbance.alpha: demonstrations: estimate it before the problem"),
    (lambda: GPMPCProblem(_wall_functions(), 1, f_ref_target=[1.0, 2.0]),
     "controller.mpc.f_ref_target: needs 1 value, got [1.0, 2.0]"),
    (lambda: MPCSettings.parse({"joint_torque": {"shoulder": [1, 2]}}, "mpc"),
     "mpc.joint_torque.shoulder: needs 1 or 3 values, got [1, 2]"),
    (lambda: MPCSettings.parse({"joint_torque": {"l1": 0}}, "mpc"),
     "mpc.joint_torque.l1: must be > 0, got 0"),
    (lambda: MPCSettings.parse({"joint_torque": {"l2": -1}}, "mpc"),
     "mpc.joint_torque.l2: must be > 0, got -1"),
]  # fmt: skip


@pytest.mark.parametrize(("build", "line"), REFUSALS, ids=[r[1].split(":")[0] for r in REFUSALS])
def test_each_bad_setting_is_refused_on_one_line_naming_its_key(build, line: str) -> None:
    """The whole line: the key a user typed and the rule it broke (a wrong length was a
    numpy broadcast traceback for ``f_ref_target`` and the arm's ``shoulder``; the demo
    impedance's refusal named ``init_*``; a negative damping was said to need > 0)."""
    assert refusal(ConfigError, build) == line

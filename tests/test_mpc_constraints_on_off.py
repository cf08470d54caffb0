"""Seed B Eq. 15 and 18-20, on and off (issue #37): the human joint-torque cost with the
measured or the predicted velocity, the force chance constraint and the well-damped constraint,
each in a small problem whose solution must move the way seed B says (cases:
``tests/mpc_cases.py``). The constraints sit at their bound when active, at the value the
paper's equation gives there.
"""

from __future__ import annotations

import math

import numpy as np
import pytest
import scipy.optimize
import scipy.special
import scipy.stats

from ccm.control.mpc.problem import GPMPCProblem, MPCSolution
from ccm.control.mpc.settings import Weights
from ccm.control.mpc.terms import joint_torque_cost
from tests.mpc_cases import (
    HAND,
    TS,
    H,
    _solve,
)
from tests.mpc_cases import (
    flat_pos as flat_pos_gp,
)
from tests.mpc_cases import (
    free2 as free2_gp,
)
from tests.mpc_cases import (
    wall as wall_gp,
)

JT = {"joint_torque": {"velocity": "measured"}}  # default arm: shoulder (0, -0.4, 0.3), z = 0


def test_joint_torque_with_measured_velocity_lowers_damping_along_the_motion() -> None:
    """Eq. 15 with f_H = D ẋ, ẋ the measured velocity (0.1, 0) m/s (seed B §4.2.2): the cost
    D_x² ẋ_x² Σ_k c(x_k) with c = e_xᵀ J_H J_Hᵀ e_x falls with D_x; D_y gets no gradient.
    f^r is frozen so that the posture (J_H depends on the hand pose) is not a lever; then
    D_x = D_prev Q_dD / (Q_dD + Q_τ ẋ_x² Σ_k c(x_k)) (first-order condition)."""
    free2 = free2_gp()
    xi0 = [*HAND, 0.1, 0.0]
    imp = {"mass": [5.0, 5.0], "damping": [1500.0, 1500.0]}
    kw = {"f_ref_max": 1e-9, "f_ref_rate_max": 1e-9, **JT, **imp}
    base = {"vel": 0.0, "delta_mass": 1.0, "delta_damping": 0.05}
    off = _solve([free2], Weights(**base), xi0, **kw)
    on = _solve([free2], Weights(**base, joint_torque=1.0), xi0, **kw)
    arm = (np.array([0.0, -0.4, 0.3]), 0.30, 0.35)  # settings.py's defaults
    c = sum(
        joint_torque_cost(np.r_[p[:2], 0.0], [1.0, 0.0, 0.0], 1.0, *arm)
        for p in on.predicted[0, 1:]
    )
    d_x = 1500.0 * 0.05 / (0.05 + 0.1**2 * c)
    assert off.damping == pytest.approx([1500.0, 1500.0], abs=1e-2)
    # the coast ẋ M / D < 0.5 mm: c hardly depends on D_x (the condition above ignores it)
    assert on.damping[0] == pytest.approx(d_x, rel=1e-2)
    assert on.damping[0] < off.damping[0] - 200.0  # d_x: 1500 -> 1163 N s/m here
    assert on.damping[1] == pytest.approx(1500.0, abs=1.0)  # across the motion: unchanged
    # with f^r free (cheap: Q_u 1e-3) the plan also shifts the hand 2 mm in −y toward a better
    # posture; at this Q_u on ΔD the damping is unmoved by that (with Q_u on ΔD ≈ 0 D_y drops
    # too, to help the shift: observed, not asserted)
    free = _solve([free2], Weights(**base, f_ref=1e-3, joint_torque=1.0), xi0,
                  **{**kw, "f_ref_max": 30.0, "f_ref_rate_max": 10.0})  # fmt: skip
    assert free.damping[0] == pytest.approx(on.damping[0], rel=1e-2)
    assert free.damping[1] == pytest.approx(1500.0, abs=1.0)
    # a flipped sign (−Q_τ) would raise D_x (to the rate limit); fails.


def test_joint_torque_with_predicted_velocity_brakes_the_plan() -> None:
    """Eq. 15 with f_H = D ẋ, ẋ the plan's own velocity: the optimiser can zero ẋ_{t+1} with
    f^r (M ẋ_t / (M + T_s D) · M / T_s = 12.5 N at D = 1500, inside the 20 N rate limit) and
    make the cost ~0, instead of lowering D. Observed over Q_u on f^r 1e-3..1 and on ΔD
    1e-6..1e-2: f^r_x 7.6-12.5 N > 0 opposes the +x motion, ẋ_{t+1} falls to 0.1-34 % of the
    free plan's (34 % at Q_u = 1, where braking costs most) and D_x never falls (1500-2000).
    Asserted for this case (Q_u = 1e-2, where ẋ_{t+1} falls to 0.3 %): the braking and D_x."""
    free2 = free2_gp()
    xi0 = [*HAND, 0.1, 0.0]
    imp = {"mass": [5.0, 5.0], "damping": [1500.0, 1500.0]}
    kw = {"f_ref_max": 30.0, "f_ref_rate_max": 20.0, "joint_torque": {"velocity": "predicted"}}
    base = {"vel": 0.0, "f_ref": 1e-2, "delta_mass": 1.0, "delta_damping": 1e-6}
    off = _solve([free2], Weights(**base), xi0, **kw, **imp)
    on = _solve([free2], Weights(**base, joint_torque=1.0), xi0, **kw, **imp)
    assert off.f_ref[0] == pytest.approx(0.0, abs=1e-3)
    assert on.f_ref[0] > 5.0
    assert abs(on.predicted[0, 1, 2]) < 0.1 * off.predicted[0, 1, 2]
    assert on.damping[0] >= off.damping[0] - 1.0
    # a flipped sign (−Q_τ) would reward speed: f^r_x < 0, ẋ_{t+1} up; fails.


# --------------------------------------------------------------------------- Eq. 18
WALL_W = Weights(vel=1e-3, f_ref_target=1.0, delta_mass=1e-3, delta_damping=1e-6)
WALL_KW = {"f_ref_target": -20.0, "f_ref_rate_max": 10.0}  # push +x into the wall
WALL_XI = [-0.0005, 0.05]  # 0.5 mm before the wall at 5 cm/s


def _quantile(form: str, eps: float) -> float:
    """Eq. 18's factor, from scipy: erf⁻¹(1 − ε) as printed, or the normal Φ⁻¹(1 − ε)."""
    if form == "paper_erfinv":
        return float(scipy.special.erfinv(1.0 - eps))
    return float(scipy.stats.norm.ppf(1.0 - eps))


@pytest.mark.parametrize(
    ("form", "eps"), [("paper_erfinv", 0.5), ("normal", 0.5), ("paper_erfinv", 0.05),
                      ("normal", 0.05)],
)  # fmt: skip
def test_chance_constraint_caps_the_mean_force(form: str, eps: float) -> None:
    """Eq. 18 at ξ_{t+H}: off, the plan ends 0.9 mm in the wall (|μ^f| ≈ 42 N > f̄ = 12 N);
    on, it is active: μ^f(x_H) = −(f̄ − q √Σ^f(x_H)), q from scipy."""
    wall = wall_gp()
    f_max = 12.0
    off = _solve([wall], WALL_W, WALL_XI, **WALL_KW)
    chance = {"f_max": f_max, "epsilon": eps, "quantile": form}
    on = _solve([wall], WALL_W, WALL_XI, chance=chance, **WALL_KW)
    mu_off = wall.predict(off.predicted[0, -1:, :1])[0][0, 0]
    mu_on, var_on = (v[0, 0] for v in wall.predict(on.predicted[0, -1:, :1]))
    assert mu_off < -f_max - 10.0
    # IPOPT's constraint violation at convergence is < 1e-6; 1e-4 N leaves room
    assert mu_on == pytest.approx(-(f_max - _quantile(form, eps) * math.sqrt(var_on)), abs=1e-4)
    assert on.predicted[0, -1, 0] < off.predicted[0, -1, 0]  # held back from the wall
    # a flipped margin (+q √Σ^f) or direction would put μ^f elsewhere; fails (q > 0 cases).


def test_chance_quantile_forms_differ_at_half() -> None:
    """At ε = 0.5 (seed B §6.1) the printed erf⁻¹(0.5) = 0.4769 keeps 0.4769 √Σ^f of margin;
    Φ⁻¹(0.5) = 0 bounds the mean only. The two plans' end forces differ by exactly that."""
    wall = wall_gp()
    sols = {
        form: _solve([wall], WALL_W, WALL_XI, **WALL_KW,
                     chance={"f_max": 12.0, "epsilon": 0.5, "quantile": form})
        for form in ("paper_erfinv", "normal")
    }  # fmt: skip
    mu, var = {}, {}
    for form, sol in sols.items():
        m, v = wall.predict(sol.predicted[0, -1:, :1])
        mu[form], var[form] = m[0, 0], v[0, 0]
    assert mu["normal"] == pytest.approx(-12.0, abs=1e-4)
    margin = 0.4769362762 * math.sqrt(var["paper_erfinv"])  # erf⁻¹(0.5)
    assert margin > 0.1  # Σ^f ≈ 0.08 N² here: a 0.135 N difference, 1000× the tolerance
    assert mu["paper_erfinv"] - mu["normal"] == pytest.approx(margin, abs=1e-4)
    # swapping the two forms (or q = 0 for both) gives a difference of −margin or 0; fails.


# --------------------------------------------------------------------------- Eq. 19-20
def test_well_damped_with_fixed_stiffness_sets_the_damping() -> None:
    """Eq. 20 with the fixed K_e = 20 kN/m: off, D stays at 500 N s/m (below the bound); on,
    the constraint is active and D = 2 ζ √(M K_e) = 759 N s/m at M = 5 kg, ζ = 1.2."""
    flat_pos = flat_pos_gp()
    w = Weights(vel=1.0, delta_mass=1e-3, delta_damping=1e-6)
    wd = {"zeta": 1.2, "stiffness": "fixed", "fixed_stiffness": 20000.0}
    off = _solve([flat_pos], w, [0.0, 0.0])
    on = _solve([flat_pos], w, [0.0, 0.0], well_damped=wd)
    need = 2 * 1.2 * math.sqrt(on.mass[0] * 20000.0)
    assert off.damping[0] < 2 * 1.2 * math.sqrt(off.mass[0] * 20000.0) - 200.0
    assert on.damping[0] == pytest.approx(need, rel=1e-4)  # active: Q_u on ΔD pulls D down
    assert on.damping[0] > off.damping[0] + 250.0
    # the constraint flipped (D ≤ bound) would leave D at 500; fails.


def test_well_damped_with_the_gp_stiffness_sets_the_damping() -> None:
    """Eq. 19-20 with K_e = −dμ^f/dx of the GP along the plan (numpy gradient here): entering
    the wall, on, D equals the largest 2 ζ √(M K_e(x_k)) over ξ_{t+1..t+H} (≈ 1340 N s/m);
    off, D stays ≈ 500 N s/m, far below what its own (deeper) plan would need."""
    wall = wall_gp()
    xi0 = [-0.001, 0.05]
    kw = {"f_ref_target": -20.0, "f_ref_rate_max": 10.0, "delta_damping_max": 5000.0}
    off = _solve([wall], WALL_W, xi0, **kw)
    on = _solve([wall], WALL_W, xi0, well_damped={"zeta": 1.2}, **kw)

    def need(sol: MPCSolution) -> float:
        k_e = [-wall.models[0].mean_gradient(p[:1])[0] for p in sol.predicted[0, 1:]]
        return max(2 * 1.2 * math.sqrt(sol.mass[0] * max(k, 0.0)) for k in k_e)

    assert on.damping[0] == pytest.approx(need(on), rel=1e-3)
    assert off.damping[0] < need(off) - 500.0
    assert on.damping[0] > off.damping[0] + 500.0
    # the constraint flipped (D ≤ bound) would leave D near 500; fails.


def test_chance_constraint_is_inactive_where_both_sides_hold() -> None:
    """Eq. 18 bounds |μ^f| from both sides: f̄ − μ^f − q √Σ^f ≥ 0 and f̄ + μ^f − q √Σ^f ≥ 0.
    3 cm in front of the wall, at rest, the GP's free-space force (|μ^f| ≈ 0.16 N) meets a
    bound of f̄ = 0.5 N with q = 0 on both sides: the plan is the unconstrained one. (A
    bound shifted by a newton on either side would make it infeasible there.)"""
    wall = wall_gp()
    xi0 = [-0.03, 0.0]
    kw = {"f_ref_target": 0.0, "f_ref_rate_max": 10.0}
    off = _solve([wall], WALL_W, xi0, **kw)
    chance = {"f_max": 0.5, "epsilon": 0.5, "quantile": "normal"}
    on = _solve([wall], WALL_W, xi0, chance=chance, **kw)
    mu_end = wall.predict(on.predicted[0, -1:, :1])[0][0, 0]
    assert abs(mu_end) < 0.5
    np.testing.assert_allclose(on.predicted, off.predicted, atol=1e-6)
    np.testing.assert_allclose(on.f_ref, off.f_ref, atol=1e-6)


def test_a_failed_solve_leaves_no_warm_start() -> None:
    """Eq. 18 with f̄ = 0.6 N below the margin q √Σ^f + |μ^f| of free space: a solve from
    3 cm before the wall is infeasible; the next one (0.5 mm in the wall, feasible) starts
    cold, as a fresh problem's first solve does, not from the failed iterate."""
    wall = wall_gp()
    chance = {"f_max": 0.6, "epsilon": 0.05, "quantile": "normal"}

    def problem() -> GPMPCProblem:
        return GPMPCProblem([wall.casadi_functions()], 1, weights=WALL_W, horizon=H, ts=TS,
                            f_ref_max=30.0, chance=chance, **WALL_KW)  # fmt: skip

    imp = ([1.0], [5.0], [500.0], [0.0])
    prob = problem()
    failed = prob.solve([-0.03, 0.0], *imp)
    assert not failed.success
    after, fresh = prob.solve([0.0005, 0.0], *imp), problem().solve([0.0005, 0.0], *imp)
    assert after.success and fresh.success
    assert after.iterations == fresh.iterations
    np.testing.assert_array_equal(after.predicted, fresh.predicted)

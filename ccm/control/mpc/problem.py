"""The GP-MPC optimisation problem of Haninger et al. (seed B §4, Eq. 13-20), in casadi.

Multiple shooting (Eq. 13): for every mode n (human goal) the predicted means
μⁿ_1..μⁿ_H are decision variables tied to the admittance dynamics of Eq. 7 by continuity
constraints |μⁿ_{τ+1} − f(μⁿ_τ, u_τ)| ≤ ϱ (ϱ = ``continuity_slack``, 0 = equality). The
covariance of Eq. 8 starts at Σ_t = 0 (state fully observed, seed B §4.1) and is propagated
as an expression of the decision variables; with diagonal M, D and Σ_f it stays block
diagonal per DOF, so its trace is exact at no extra cost.

Decision variables u (seed B §4.1): the force reference f^r over the horizon and one change
of the impedance ΔM, ΔD per solve (M = M_prev + ΔM, D = D_prev + ΔD, held over the horizon),
with bounds and rate limits. The stage cost is Eq. 14 in its trace form with seed B's
semi-implicit integrator (§5.2: convex in (M, D) from a small Σ_f on, ``ccm run
experiment=mpc_convexity``), summed over modes with the belief b[n] as weight (Eq. 13).
Optional terms (each off unless configured): the force chance constraint (Eq. 18), the
well-damped constraint (Eq. 19-20), the disturbance-rejection cost (Eq. 16-17) and the human
joint-torque cost (Eq. 11, 15), whose models live in :mod:`ccm.control.mpc.terms`. With
``force_cost: human_match`` the force term μ^fᵀ Q_f μ^f becomes seed B §4.2.1's
(μ^f_τ + f^r_τ)ᵀ Q_H (μ^f_τ + f^r_τ) "to match the human demonstrations": f^r is pulled to
−μ^f, so the robot renders the demonstrated force itself; summed over the modes with the
belief as weight (Eq. 13), it pulls f^r to −Σ_n b[n] μ^{f,n}, which ties the plan's force to
the believed goal.

IPOPT solves it, warm-started from the previous primal and dual solution
(``warm_start_init_point``). A solve that IPOPT does not report as successful is *not*
applied: :meth:`GPMPCProblem.solve` returns ``success=False`` and the caller keeps its last
feasible command and counts the event.
"""

from __future__ import annotations

import math
from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass
from typing import Any

import casadi as ca
import numpy as np

from ccm.control.mpc.admittance import system_matrices
from ccm.control.mpc.codegen import make_solver
from ccm.control.mpc.settings import MPCSettings, vector
from ccm.control.mpc.terms import disturbance_h2, joint_torque_cost
from ccm.core.errors import (
    ConfigError,
    check_int_positive,
)

GPFunctions = Mapping[str, ca.Function]  # "mean", "var", "grad" of one mode (gp_force.py)


@dataclass
class MPCSolution:
    """One solve: the first force reference and the new impedance (Eq. 13's u_t)."""

    success: bool
    status: str
    f_ref: np.ndarray  # (n,) f^r_t [N]
    mass: np.ndarray  # (n,) M_t [kg]
    damping: np.ndarray  # (n,) D_t [N s/m]
    iterations: int
    predicted: np.ndarray  # (N_modes, H+1, 2n) predicted means, row 0 = ξ_t


class _Constraints:
    """The constraint rows g(w, p) of the NLP with their bounds, in the order added."""

    def __init__(self) -> None:
        self.exprs: list[ca.MX] = []
        self.lower: list[float] = []
        self.upper: list[float] = []

    def add(self, expr: ca.MX, lo: float, hi: float) -> None:
        self.exprs.append(expr)
        self.lower.extend([lo] * expr.numel())
        self.upper.extend([hi] * expr.numel())


@dataclass(frozen=True)
class _ModeTerms:
    """What every mode's terms share: the discretised admittance (A, B), M and D, the f^r
    variables, the slack and the GP-variance factor, and the optional constraint settings."""

    a_b: tuple[ca.MX, ca.MX]
    mass: ca.MX
    damping: ca.MX
    fr: list[ca.MX]
    slack: float
    var_scale: float
    chance: tuple[float, float] | None
    wd: tuple[float, float | None] | None
    jt: Callable[[ca.MX, ca.MX], ca.MX] | None
    human_match: bool  # §4.2.1: (μ^f + f^r)ᵀ Q_H (μ^f + f^r) instead of μ^fᵀ Q_f μ^f
    jt_measured: bool  # §4.2.2: f_H = D ẋ with ẋ the measured velocity (a parameter)


def _ipopt_options(extra: Mapping[str, Any] | None) -> dict[str, Any]:
    """IPOPT settings for warm-started solves, then the config's ``ipopt`` entries."""
    opts = {
        "ipopt.print_level": 0,
        "print_time": False,
        "ipopt.sb": "yes",
        "ipopt.max_iter": 100,
        "ipopt.tol": 1e-6,
        "ipopt.warm_start_init_point": "yes",
        # a warm start sits near the optimum: a small barrier parameter and bound pushes
        # keep IPOPT there (8 instead of 24 iterations per solve, measured in make bench)
        "ipopt.mu_init": 1e-4,
        "ipopt.warm_start_bound_push": 1e-6,
        "ipopt.warm_start_mult_bound_push": 1e-6,
        "ipopt.warm_start_slack_bound_push": 1e-6,
        "expand": True,  # SX graph: ~3x faster function evaluations than MX
    }
    for k, v in (extra or {}).items():
        opts[f"ipopt.{k}"] = v
    return opts


class GPMPCProblem:
    """Builds Eq. 13 once for fixed GP models; :meth:`solve` is called at the MPC rate.

    Args:
        gp_modes: one set of casadi GP functions per mode n (``GPForceModels.casadi_functions``).
        n: task-space dimension (force and pose dimension of the GPs).
        key: configuration-key prefix for errors.

    Keyword Args:
        horizon (int): H, steps.
        ts (float): MPC sample time T_s [s] of Eq. 5.
        mass_bounds (tuple[float, float]): [min, max] of M_i [kg].
        damping_bounds (tuple[float, float]): [min, max] of D_i [N s/m].
        delta_mass_max (float): rate limit |ΔM_i| per solve.
        delta_damping_max (float): rate limit |ΔD_i| per solve.
        f_ref_max (float): bound |f^r_i| [N].
        f_ref_rate_max (float): |f^r_{τ+1} − f^r_τ| [N] per step, also from the previous
            solve's f^r.
        f_ref_target (float | Sequence[float]): the target of the f^r-target cost [N] (n,).
        force_cost (str): ``"mean"`` (μ^fᵀ Q_f μ^f, Eq. 14) or ``"human_match"``
            ((μ^f + f^r)ᵀ Q_H (μ^f + f^r), seed B §4.2.1), both weighted by ``weights.force``.
        weights (Weights | Mapping): cost weights (:class:`ccm.control.mpc.settings.Weights`,
            or a mapping).
        continuity_slack (float): ϱ of Eq. 13.
        gp_var_scale (float): factor on the GP variance in the dynamics (1 = the paper; seed B's
            public reference code uses 10, a constant the paper does not state).
        chance (Mapping | None): None or {f_max [N], epsilon, quantile: "normal" |
            "paper_erfinv"} (Eq. 18).
        well_damped (Mapping | None): None or {zeta, stiffness: "gp_gradient" | "fixed",
            fixed_stiffness} (Eq. 19-20).
        disturbance (Mapping | None): {alpha, omega_p} of F^d(s) = α s / (s + ω_p) (Eq. 16-17).
        joint_torque (Mapping | None): {shoulder [m] (3,), l1, l2 [m], z [m]: the TCP height
            used to pad a 2-D pose, velocity: "measured" | "predicted"} (Eq. 11, 15; f_H = D ẋ,
            seed B §4.2.2, where ẋ "provides a weighting according to the direction of the
            expected forces": ``measured`` takes ξ_t's velocity, a parameter, so the cost acts on D;
            ``predicted`` the plan's own velocity, which the optimiser can lower instead).
        ipopt (Mapping | None): extra IPOPT options (e.g. max_iter, tol, hessian_approximation).
        codegen (str | None): None (default): casadi evaluates the NLP functions. A string: C
            compiler flags (e.g. "-O1"); the functions are generated as C, compiled once per GP fit
            and cached on disk (:mod:`ccm.control.mpc.codegen`), same solution, faster solves.

    The settings are checked by :meth:`ccm.control.mpc.settings.MPCSettings.parse`.
    """

    def __init__(
        self,
        gp_modes: Sequence[GPFunctions],
        n: int,
        *,
        key: str = "controller.mpc",
        **settings: Any,
    ) -> None:
        if not gp_modes:
            raise ConfigError(f"{key}.modes", "needs at least one mode's GP models")
        self.n = n = check_int_positive(f"{key}.n", n)
        self.n_modes = len(gp_modes)
        self.key = key
        st = self.settings = MPCSettings.parse(settings, key)
        self.horizon = H = st.horizon
        self.ts, self.mass_bounds, self.damping_bounds = st.ts, st.mass_bounds, st.damping_bounds
        self.delta_mass_max, self.delta_damping_max = st.delta_mass_max, st.delta_damping_max
        self.f_ref_max, self.f_ref_rate_max = st.f_ref_max, st.f_ref_rate_max
        self.w = st.weights
        if st.disturbance is not None and math.isnan(st.disturbance[0]):
            raise ConfigError(
                f"{key}.disturbance.alpha", "demonstrations: estimate it before the problem"
            )
        target = vector(f"{key}.f_ref_target", st.f_ref_target, n)
        # --- symbols: parameters p = [ξ_t, b, M_prev, D_prev, f^r_prev]
        xi0 = ca.MX.sym("xi0", 2 * n)
        belief = ca.MX.sym("belief", self.n_modes)
        m_prev, d_prev, fr_prev = (ca.MX.sym(s, n) for s in ("m_prev", "d_prev", "fr_prev"))
        # --- decision variables w = [f^r_0..H-1, ΔM, ΔD, μ^n_1..H for each mode]
        fr = [ca.MX.sym(f"fr{k}", n) for k in range(H)]
        dm, dd = ca.MX.sym("dm", n), ca.MX.sym("dd", n)
        mus = [
            [ca.MX.sym(f"mu{m}_{k}", 2 * n) for k in range(1, H + 1)] for m in range(self.n_modes)
        ]
        mass, damping = m_prev + dm, d_prev + dd
        g = _Constraints()
        # rate limits on f^r (linear)
        g.add(fr[0] - fr_prev, -self.f_ref_rate_max, self.f_ref_rate_max)
        for k in range(1, H):
            g.add(fr[k] - fr[k - 1], -self.f_ref_rate_max, self.f_ref_rate_max)
        cost = self._shared_cost(fr, dm, dd, mass, damping, target)
        terms = _ModeTerms(
            a_b=system_matrices(mass, damping, self.ts), mass=mass, damping=damping, fr=fr,
            slack=st.continuity_slack, var_scale=st.gp_var_scale, chance=st.chance,
            wd=st.well_damped, jt=self._joint_torque() if self.w.joint_torque > 0.0 else None,
            human_match=st.force_cost == "human_match",
            jt_measured=st.joint_torque is not None and st.joint_torque.velocity == "measured",
        )  # fmt: skip
        for m, gp in enumerate(gp_modes):
            cost += belief[m] * self._mode_cost(gp, [xi0, *mus[m]], terms, g)
        self._w = ca.vertcat(*fr, dm, dd, *[mu for mode in mus for mu in mode])
        self._p = ca.vertcat(xi0, belief, m_prev, d_prev, fr_prev)
        self._lbg, self._ubg = np.array(g.lower), np.array(g.upper)
        nlp = {"x": self._w, "p": self._p, "f": cost, "g": ca.vertcat(*g.exprs)}
        self._solver = make_solver("gp_mpc", nlp, _ipopt_options(st.ipopt), codegen=st.codegen)
        self._nw = int(self._w.numel())
        self._warm: dict[str, np.ndarray] | None = None

    # --------------------------------------------------------------------------- terms
    def _shared_cost(
        self,
        fr: list[ca.MX],
        dm: ca.MX,
        dd: ca.MX,
        mass: ca.MX,
        damping: ca.MX,
        target: np.ndarray,
    ) -> ca.MX:
        """The cost terms every mode shares: f^r, its target, ΔM, ΔD and Eq. 16-17."""
        cost = self.w.f_ref * sum(ca.sumsqr(f) for f in fr)
        cost += self.w.f_ref_target * sum(ca.sumsqr(f - target) for f in fr)
        cost += self.w.delta_mass * ca.sumsqr(dm) + self.w.delta_damping * ca.sumsqr(dd)
        if self.settings.disturbance is not None:  # Eq. 16-17, per DOF, K dropped (§3.2)
            alpha, omega = self.settings.disturbance
            cost += self.w.disturbance * sum(
                disturbance_h2(mass[i], damping[i], 0.0, alpha, omega) for i in range(self.n)
            ) * self.horizon  # fmt: skip
        return cost

    def _joint_torque(self) -> Callable[[ca.MX, ca.MX], ca.MX]:
        """Eq. 15's cost of a hand pose and force (2-D poses padded to the TCP height z)."""
        arm = self.settings.joint_torque
        assert arm is not None  # set whenever its weight is on
        pad = 3 - self.n

        def cost(pose: ca.MX, f_hand: ca.MX) -> ca.MX:
            x3 = ca.vertcat(pose, *([arm.z] * pad)) if pad else pose
            f3 = ca.vertcat(f_hand, *([0.0] * pad)) if pad else f_hand
            return joint_torque_cost(x3, f3, ca.DM.eye(4), arm.shoulder, arm.l1, arm.l2)

        return cost

    def _mode_cost(
        self, gp: GPFunctions, states: list[ca.MX], t: _ModeTerms, g: _Constraints
    ) -> ca.MX:
        """One mode's stage costs over the horizon, adding its dynamics (Eq. 7-8), well-damped
        (Eq. 19-20) and chance (Eq. 18) constraints to ``g``."""
        n, w = self.n, self.w
        mean_f, var_f, grad_f = gp["mean"], gp["var"], gp["grad"]
        a, b = t.a_b
        poses = [st[:n] for st in states]
        f_mu = [mean_f(x) for x in poses]  # GP at μ_t..μ_{t+H}: dynamics use 0..H-1,
        f_var = [t.var_scale * var_f(x) for x in poses]  # the stage costs 1..H
        sigma = ca.MX.zeros(2 * n, 2 * n)
        mode_cost = 0
        for k in range(self.horizon):
            nxt = a @ states[k] + b @ (f_mu[k] - t.fr[k])  # Eq. 7
            sigma = a @ sigma @ a.T + b @ ca.diag(f_var[k]) @ b.T  # Eq. 8
            g.add(states[k + 1] - nxt, -t.slack, t.slack)
            mu_next, fm_n, fv_n = states[k + 1], f_mu[k + 1], f_var[k + 1]
            diag_s = ca.diag(sigma)
            mode_cost += w.vel * ca.sumsqr(mu_next[n:])
            mode_cost += w.pos_var * ca.sum1(diag_s[:n])
            mode_cost += w.vel_var * ca.sum1(diag_s[n:])
            if t.human_match:  # §4.2.1: f^r_τ matches the demonstrated force at its own step
                mode_cost += w.force * ca.sumsqr(f_mu[k] + t.fr[k])
            else:
                mode_cost += w.force * ca.sumsqr(fm_n)
            mode_cost += w.force_var * ca.sum1(fv_n)
            if t.jt is not None:  # Eq. 15 with f_H = D ẋ (seed B §4.2.2)
                xdot = states[0][n:] if t.jt_measured else mu_next[n:]
                mode_cost += w.joint_torque * t.jt(poses[k + 1], t.damping * xdot)
            if t.wd is not None:  # Eq. 19-20 on ξ_{t+1..t+H}; D² ≥ 4ζ²M K_e (D > 0)
                zeta, fixed = t.wd
                k_e = fixed if fixed is not None else -ca.diag(grad_f(poses[k + 1]))
                g.add(t.damping**2 - 4.0 * zeta**2 * t.mass * k_e, 0.0, ca.inf)
            if t.chance is not None and k == self.horizon - 1:  # Eq. 18 at ξ_{t+H}, ±
                f_max, q = t.chance
                margin = q * ca.sqrt(fv_n + 1e-12)
                g.add(f_max - fm_n - margin, 0.0, ca.inf)
                g.add(f_max + fm_n - margin, 0.0, ca.inf)
        return mode_cost

    # --------------------------------------------------------------------------- solve
    def bounds(self, m_prev: np.ndarray, d_prev: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Variable bounds for this solve: |f^r| ≤ f_max; ΔM, ΔD within the rate limits and
        so that M, D stay inside their bounds; predicted states free."""
        n, H = self.n, self.horizon
        lo = np.full(self._nw, -np.inf)
        hi = np.full(self._nw, np.inf)
        lo[: n * H], hi[: n * H] = -self.f_ref_max, self.f_ref_max
        (m_lo, m_hi), (d_lo, d_hi) = self.mass_bounds, self.damping_bounds
        s = n * H
        lo[s : s + n] = np.maximum(-self.delta_mass_max, m_lo - m_prev)
        hi[s : s + n] = np.minimum(self.delta_mass_max, m_hi - m_prev)
        lo[s + n : s + 2 * n] = np.maximum(-self.delta_damping_max, d_lo - d_prev)
        hi[s + n : s + 2 * n] = np.minimum(self.delta_damping_max, d_hi - d_prev)
        return lo, np.maximum(hi, lo)

    def initial_guess(self, xi0: np.ndarray, fr_prev: np.ndarray) -> np.ndarray:
        """Cold start: f^r held, no impedance change, every mode's states at ξ_t."""
        n, H = self.n, self.horizon
        return np.concatenate(
            [np.tile(fr_prev, H), np.zeros(2 * n), np.tile(xi0, H * self.n_modes)]
        )

    def solve(
        self,
        xi0: Any,
        belief: Any,
        m_prev: Any,
        d_prev: Any,
        fr_prev: Any,
    ) -> MPCSolution:
        """Solve Eq. 13 from state ξ_t = [x, ẋ] with belief b_t and the current impedance.

        Warm start: the previous solve's primal and dual solution (cold start the first
        time or after :meth:`reset_warm_start`).
        """
        n, H = self.n, self.horizon
        xi0 = np.asarray(xi0, float).reshape(2 * n)
        m_prev, d_prev, fr_prev = (
            np.asarray(v, float).reshape(n) for v in (m_prev, d_prev, fr_prev)
        )
        p = np.concatenate(
            [xi0, np.asarray(belief, float).reshape(self.n_modes), m_prev, d_prev, fr_prev]
        )
        lbx, ubx = self.bounds(m_prev, d_prev)
        args: dict[str, Any] = {"p": p, "lbx": lbx, "ubx": ubx, "lbg": self._lbg, "ubg": self._ubg}
        if self._warm is None:
            args["x0"] = np.clip(self.initial_guess(xi0, fr_prev), lbx, ubx)
        else:
            args["x0"] = np.clip(self._warm["x"], lbx, ubx)
            args["lam_x0"], args["lam_g0"] = self._warm["lam_x"], self._warm["lam_g"]
        sol = self._solver(**args)
        stats = self._solver.stats()
        ok = bool(stats.get("success", False))
        x = np.asarray(sol["x"]).ravel()
        if ok and np.all(np.isfinite(x)):
            self._warm = {
                "x": x,
                "lam_x": np.asarray(sol["lam_x"]).ravel(),
                "lam_g": np.asarray(sol["lam_g"]).ravel(),
            }
        else:
            ok = False
            self._warm = None  # restart cold: a failed iterate is a poor initial point
        s = n * H
        states = x[s + 2 * n :].reshape(self.n_modes, H, 2 * n)
        predicted = np.concatenate([np.broadcast_to(xi0, (self.n_modes, 1, 2 * n)), states], axis=1)
        return MPCSolution(
            success=ok,
            status=str(stats.get("return_status", "unknown")),
            f_ref=x[:n].copy(),
            mass=m_prev + x[s : s + n],
            damping=d_prev + x[s + n : s + 2 * n],
            iterations=int(stats.get("iter_count", -1)),
            predicted=predicted,
        )

    def reset_warm_start(self) -> None:
        """Forget the previous solution (a new trial)."""
        self._warm = None

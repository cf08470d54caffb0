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
joint-torque cost (Eq. 11, 15), whose models live in :mod:`ccm.control.mpc.terms`.

IPOPT solves it, warm-started from the previous primal and dual solution
(``warm_start_init_point``). A solve that IPOPT does not report as successful is *not*
applied: :meth:`GPMPCProblem.solve` returns ``success=False`` and the caller keeps its last
feasible command and counts the event.
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from dataclasses import dataclass
from typing import Any

import casadi as ca
import numpy as np

from ccm.control.mpc.admittance import system_matrices
from ccm.control.mpc.codegen import make_solver
from ccm.control.mpc.terms import chance_quantile, disturbance_h2, joint_torque_cost
from ccm.core.errors import (
    ConfigError,
    check_bounds,
    check_int_positive,
    check_keys,
    check_nonneg,
    check_positive,
)

GPFunctions = Mapping[str, ca.Function]  # "mean", "var", "grad" of one mode (gp_force.py)


@dataclass(frozen=True)
class Weights:
    """Cost weights of Eq. 14 (diagonal Q's; scalars apply to every DOF).

    Attributes:
        vel: Q_μ on velocity ("just a small penalty on velocity", seed B §4.2.1).
        pos_var, vel_var: Q_Σ on the position and velocity variances (trace form, §5.2).
        force: Q_f on the GP mean force μ^f.
        force_var: Q_Σ,f on the GP variance Σ^f.
        f_ref: Q_u on f^r.
        delta_mass, delta_damping: Q_u on ΔM, ΔD.
        f_ref_target: weight on ‖f_target − f^r‖² (seed B §6.2's "‖15 − f^r_2‖" cost).
        joint_torque: Q_τ of Eq. 15 (0 = off).
        disturbance: weight on ‖X^d‖²₂ of Eq. 16 per DOF (0 = off).
    """

    vel: float = 1.0
    pos_var: float = 0.0
    vel_var: float = 0.0
    force: float = 0.0
    force_var: float = 0.0
    f_ref: float = 0.0
    delta_mass: float = 0.0
    delta_damping: float = 0.0
    f_ref_target: float = 0.0
    joint_torque: float = 0.0
    disturbance: float = 0.0


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


def _only(key: str, block: Mapping[str, Any], allowed: Sequence[str]) -> None:
    """Reject keys of an option block that are not in ``allowed``."""
    if not isinstance(block, Mapping):
        raise ConfigError(key, f"must be a mapping with keys {', '.join(allowed)}")
    check_keys(key, block, allowed)


def check_settings(cfg: Mapping[str, Any], key: str = "controller.mpc") -> None:
    """Validate the ``controller.mpc`` block before any model exists (one clear error at
    start-up instead of after the demonstrations): the same checks as the constructor."""
    import inspect

    params = inspect.signature(GPMPCProblem.__init__).parameters
    allowed = [p for p in params if p not in ("self", "gp_modes", "n", "key")]
    _only(key, cfg, allowed)
    kw = dict(cfg)
    weights = kw.pop("weights", None) or {}
    _only(f"{key}.weights", weights, list(Weights.__dataclass_fields__))
    for name, val in weights.items():
        check_nonneg(f"{key}.weights.{name}", val)
    probe = GPMPCProblem.__new__(GPMPCProblem)
    probe.key, probe.n = key, 2
    check_int_positive(f"{key}.horizon", kw.get("horizon", 10))
    check_positive(f"{key}.ts", kw.get("ts", 0.02))
    for name in ("mass_bounds", "damping_bounds"):
        if name in kw:
            check_bounds(f"{key}.{name}", kw[name])
    if "mass_bounds" in kw and check_bounds(f"{key}.mass_bounds", kw["mass_bounds"])[0] <= 0:
        raise ConfigError(f"{key}.mass_bounds", "minimum mass must be > 0")
    for name in ("delta_mass_max", "delta_damping_max", "continuity_slack"):
        if name in kw:
            check_nonneg(f"{key}.{name}", kw[name])
    for name in ("f_ref_max", "f_ref_rate_max", "gp_var_scale"):
        if name in kw:
            check_positive(f"{key}.{name}", kw[name])
    probe._chance_setup(kw.get("chance"))
    probe._well_damped_setup(kw.get("well_damped"))
    if kw.get("joint_torque"):
        probe._joint_torque_setup(kw["joint_torque"])
    if kw.get("disturbance"):
        _only(f"{key}.disturbance", kw["disturbance"], ("alpha", "omega_p"))


def _vec(key: str, value: Any, n: int) -> np.ndarray:
    arr = np.broadcast_to(np.asarray(value, dtype=float), (n,)).copy()
    if not np.all(np.isfinite(arr)):
        raise ConfigError(key, f"must be finite, got {value!r}")
    return arr


class GPMPCProblem:
    """Builds Eq. 13 once for fixed GP models; :meth:`solve` is called at the MPC rate.

    Args:
        gp_modes: one set of casadi GP functions per mode n (``GPForceModels.casadi_functions``).
        n: task-space dimension (force and pose dimension of the GPs).
        horizon: H, steps.
        ts: MPC sample time T_s [s] of Eq. 5.
        mass_bounds, damping_bounds: [min, max] of M_i [kg] and D_i [N s/m].
        delta_mass_max, delta_damping_max: rate limits |ΔM_i|, |ΔD_i| per solve.
        f_ref_max: bound |f^r_i| [N]; f_ref_rate_max: |f^r_{τ+1} − f^r_τ| [N] per step,
            also from the previous solve's f^r.
        f_ref_target: the target of the f^r-target cost [N] (n,).
        weights: cost weights (:class:`Weights`).
        continuity_slack: ϱ of Eq. 13.
        gp_var_scale: factor on the GP variance in the dynamics (1 = the paper; seed B's
            public reference code uses 10, a constant the paper does not state).
        chance: None or {f_max [N], epsilon, quantile: "normal" | "paper_erfinv"} (Eq. 18).
        well_damped: None or {zeta, stiffness: "gp_gradient" | "fixed", fixed_stiffness}
            (Eq. 19-20).
        disturbance: {alpha, omega_p} of F^d(s) = α s / (s + ω_p) (Eq. 16-17).
        joint_torque: {shoulder [m] (3,), l1, l2 [m], z [m]: the TCP height used to pad a
            2-D pose} (Eq. 11, 15; f_H = D ẋ, seed B §4.2.2).
        ipopt: extra IPOPT options (e.g. max_iter, tol, hessian_approximation).
        codegen: None (default): casadi evaluates the NLP functions. A string: C compiler
            flags (e.g. "-O1"); the functions are generated as C, compiled once per GP fit
            and cached on disk (:mod:`ccm.control.mpc.codegen`), same solution, faster solves.
        key: configuration-key prefix for errors.
    """

    def __init__(
        self,
        gp_modes: Sequence[GPFunctions],
        n: int,
        *,
        horizon: int = 10,
        ts: float = 0.02,
        mass_bounds: Sequence[float] = (5.0, 60.0),
        damping_bounds: Sequence[float] = (500.0, 5000.0),
        delta_mass_max: float = 5.0,
        delta_damping_max: float = 500.0,
        f_ref_max: float = 30.0,
        f_ref_rate_max: float = 10.0,
        f_ref_target: Any = 0.0,
        weights: Weights | None = None,
        continuity_slack: float = 0.0,
        gp_var_scale: float = 1.0,
        chance: Mapping[str, Any] | None = None,
        well_damped: Mapping[str, Any] | None = None,
        disturbance: Mapping[str, Any] | None = None,
        joint_torque: Mapping[str, Any] | None = None,
        ipopt: Mapping[str, Any] | None = None,
        key: str = "controller.mpc",
        codegen: str | None = None,
    ) -> None:
        if not gp_modes:
            raise ConfigError(f"{key}.modes", "needs at least one mode's GP models")
        self.n = n = check_int_positive(f"{key}.n", n)
        self.n_modes = len(gp_modes)
        self.horizon = H = check_int_positive(f"{key}.horizon", horizon)
        self.ts = check_positive(f"{key}.ts", ts)
        self.mass_bounds = check_bounds(f"{key}.mass_bounds", mass_bounds)
        self.damping_bounds = check_bounds(f"{key}.damping_bounds", damping_bounds)
        if self.mass_bounds[0] <= 0:
            raise ConfigError(f"{key}.mass_bounds", "minimum mass must be > 0")
        self.delta_mass_max = check_nonneg(f"{key}.delta_mass_max", delta_mass_max)
        self.delta_damping_max = check_nonneg(f"{key}.delta_damping_max", delta_damping_max)
        self.f_ref_max = check_positive(f"{key}.f_ref_max", f_ref_max)
        self.f_ref_rate_max = check_positive(f"{key}.f_ref_rate_max", f_ref_rate_max)
        self.w = weights or Weights()
        for name, val in vars(self.w).items():
            check_nonneg(f"{key}.weights.{name}", val)
        target = _vec(f"{key}.f_ref_target", f_ref_target, n)
        slack = check_nonneg(f"{key}.continuity_slack", continuity_slack)
        var_scale = check_positive(f"{key}.gp_var_scale", gp_var_scale)
        self.key = key

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
        a, b = system_matrices(mass, damping, self.ts)

        g: list[ca.MX] = []
        lbg: list[float] = []
        ubg: list[float] = []

        def add(expr: ca.MX, lo: float, hi: float) -> None:
            g.append(expr)
            lbg.extend([lo] * expr.numel())
            ubg.extend([hi] * expr.numel())

        # rate limits on f^r (linear)
        add(fr[0] - fr_prev, -self.f_ref_rate_max, self.f_ref_rate_max)
        for k in range(1, H):
            add(fr[k] - fr[k - 1], -self.f_ref_rate_max, self.f_ref_rate_max)

        cost = self.w.f_ref * sum(ca.sumsqr(f) for f in fr)
        cost += self.w.f_ref_target * sum(ca.sumsqr(f - target) for f in fr)
        cost += self.w.delta_mass * ca.sumsqr(dm) + self.w.delta_damping * ca.sumsqr(dd)
        if self.w.disturbance > 0.0:  # Eq. 16-17, per DOF, K dropped (§3.2)
            dist = disturbance or {}
            _only(f"{key}.disturbance", dist, ("alpha", "omega_p"))
            alpha = check_positive(f"{key}.disturbance.alpha", dist.get("alpha", 1.0))
            omega = check_positive(
                f"{key}.disturbance.omega_p", dist.get("omega_p", 2 * np.pi * 15)
            )
            cost += self.w.disturbance * sum(
                disturbance_h2(mass[i], damping[i], 0.0, alpha, omega) for i in range(n)
            ) * H  # fmt: skip
        q_chance = self._chance_setup(chance)
        wd = self._well_damped_setup(well_damped)
        jt = self._joint_torque_setup(joint_torque) if self.w.joint_torque > 0.0 else None

        for m, gp in enumerate(gp_modes):
            mean_f, var_f, grad_f = gp["mean"], gp["var"], gp["grad"]
            states = [xi0, *mus[m]]
            poses = [st[:n] for st in states]
            f_mu = [mean_f(x) for x in poses]  # GP at μ_t..μ_{t+H}: dynamics use 0..H-1,
            f_var = [var_scale * var_f(x) for x in poses]  # the stage costs 1..H
            sigma = ca.MX.zeros(2 * n, 2 * n)
            mode_cost = 0
            for k in range(H):
                nxt = a @ states[k] + b @ (f_mu[k] - fr[k])  # Eq. 7
                sigma = a @ sigma @ a.T + b @ ca.diag(f_var[k]) @ b.T  # Eq. 8
                add(states[k + 1] - nxt, -slack, slack)
                mu_next, fm_n, fv_n = states[k + 1], f_mu[k + 1], f_var[k + 1]
                diag_s = ca.diag(sigma)
                mode_cost += self.w.vel * ca.sumsqr(mu_next[n:])
                mode_cost += self.w.pos_var * ca.sum1(diag_s[:n])
                mode_cost += self.w.vel_var * ca.sum1(diag_s[n:])
                mode_cost += self.w.force * ca.sumsqr(fm_n) + self.w.force_var * ca.sum1(fv_n)
                if jt is not None:  # Eq. 15 with f_H = D ẋ (seed B §4.2.2)
                    mode_cost += self.w.joint_torque * jt(poses[k + 1], damping * mu_next[n:])
                if wd is not None:  # Eq. 19-20 on ξ_{t+1..t+H}; D² ≥ 4ζ²M K_e (D > 0)
                    k_e = wd["fixed"] if wd["fixed"] is not None else -ca.diag(grad_f(poses[k + 1]))
                    add(damping**2 - 4.0 * wd["zeta"] ** 2 * mass * k_e, 0.0, ca.inf)
                if q_chance is not None and k == H - 1:  # Eq. 18 at ξ_{t+H}, both signs
                    margin = q_chance * ca.sqrt(fv_n + 1e-12)
                    add(self._f_max - fm_n - margin, 0.0, ca.inf)
                    add(self._f_max + fm_n - margin, 0.0, ca.inf)
            cost += belief[m] * mode_cost

        w_list = [*fr, dm, dd, *[mu for mode in mus for mu in mode]]
        self._w = ca.vertcat(*w_list)
        self._p = ca.vertcat(xi0, belief, m_prev, d_prev, fr_prev)
        self._lbg, self._ubg = np.array(lbg), np.array(ubg)
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
        for k_, v in (ipopt or {}).items():
            opts[f"ipopt.{k_}"] = v
        nlp = {"x": self._w, "p": self._p, "f": cost, "g": ca.vertcat(*g)}
        self._solver = make_solver("gp_mpc", nlp, opts, codegen=codegen)
        self._nw = int(self._w.numel())
        self._warm: dict[str, np.ndarray] | None = None

    # ------------------------------------------------------------------------- options
    def _chance_setup(self, chance: Mapping[str, Any] | None) -> float | None:
        if not chance:
            return None
        k = f"{self.key}.chance"
        _only(k, chance, ("f_max", "epsilon", "quantile"))
        self._f_max = check_positive(f"{k}.f_max", chance.get("f_max", 12.0))
        return float(
            chance_quantile(
                chance.get("epsilon", 0.5), form=chance.get("quantile", "normal"), key=k
            )
        )

    def _well_damped_setup(self, wd: Mapping[str, Any] | None) -> dict[str, Any] | None:
        if not wd:
            return None
        k = f"{self.key}.well_damped"
        _only(k, wd, ("zeta", "stiffness", "fixed_stiffness"))
        zeta = check_positive(f"{k}.zeta", wd.get("zeta", 1.2))
        source = wd.get("stiffness", "gp_gradient")
        if source not in ("gp_gradient", "fixed"):
            raise ConfigError(f"{k}.stiffness", f"must be gp_gradient or fixed, got {source!r}")
        fixed = (
            check_positive(f"{k}.fixed_stiffness", wd.get("fixed_stiffness", 700.0))
            if source == "fixed"
            else None
        )
        return {"zeta": zeta, "fixed": fixed}

    def _joint_torque_setup(self, jt: Mapping[str, Any] | None) -> Any:
        k = f"{self.key}.joint_torque"
        jt = dict(jt or {})
        _only(k, jt, ("shoulder", "l1", "l2", "z"))
        shoulder = _vec(f"{k}.shoulder", jt.get("shoulder", (0.0, -0.4, 0.3)), 3)
        l1 = check_positive(f"{k}.l1", jt.get("l1", 0.30))
        l2 = check_positive(f"{k}.l2", jt.get("l2", 0.35))
        z = float(jt.get("z", 0.0))
        n = self.n

        def cost(pose: ca.MX, f_hand: ca.MX) -> ca.MX:
            pad = 3 - n
            x3 = ca.vertcat(pose, *([z] * pad)) if pad else pose
            f3 = ca.vertcat(f_hand, *([0.0] * pad)) if pad else f_hand
            return joint_torque_cost(x3, f3, ca.DM.eye(4), shoulder, l1, l2)

        return cost

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

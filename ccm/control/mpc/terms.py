"""Cost, belief and constraint terms of seed B's GP-MPC (seed B §3.3-3.4, §4.2.2-4.3.1).

* Human arm kinematics and the joint-torque (ergonomics) cost: Eq. 10, 11, 15.
* Frequency-domain disturbance rejection from an H2 norm: Eq. 16-17.
* Bayesian mode belief over the GP force models: Eq. 12.
* The quantile of the force chance constraint: Eq. 18.

Like :mod:`ccm.control.mpc.admittance`, the arm and disturbance functions take numpy arrays or
casadi symbols (``ca.MX``/``ca.SX``/``ca.DM``) alike, so the MPC builds its cost from the same
code the tests check numerically. Vectors come back as numpy ``(n,)`` arrays or casadi
columns. The belief update runs once per control step outside the optimisation and is numpy
only.
"""

from __future__ import annotations

import math
from statistics import NormalDist
from typing import Any

import numpy as np

from ccm.core.errors import ConfigError, check_choice, check_finite, check_nonneg

# Arm segment lengths [m] assumed by ccm (seed B gives none): rough adult values, the upper
# arm shoulder-to-elbow and the forearm elbow-to-grip (forearm plus half the hand).
UPPER_ARM = 0.30
FOREARM = 0.35
# The IK keeps the elbow angle in [eps, pi - eps]: acos has an infinite slope at +-1, and
# a reach beyond l1 + l2 (or inside |l1 - l2|) is projected onto the reachable shell.
_ELBOW_EPS = 1e-3


def _lib(*xs: Any) -> Any:
    """casadi if any argument is symbolic, else numpy."""
    import casadi as ca

    return ca if any(isinstance(x, ca.MX | ca.SX | ca.DM) for x in xs) else np


def _vec(lib: Any, x: Any, n: int, key: str) -> Any:
    """``x`` as a numpy (n,) array or a casadi (n, 1) column."""
    if lib is np:
        out = np.asarray(x, dtype=float).reshape(-1)
    else:
        import casadi as ca

        out = ca.vec(x) if isinstance(x, ca.MX | ca.SX | ca.DM) else ca.DM(np.ravel(x))
    if out.shape[0] != n:
        raise ConfigError(key, f"must have {n} entries, got shape {out.shape}")
    return out


def _stack(lib: Any, rows: list[list[Any]]) -> Any:
    if lib is np:
        return np.array(rows, dtype=float)
    return lib.vertcat(*[lib.horzcat(*r) for r in rows])


def _rot(lib: Any, axis: str, angle: Any) -> Any:
    c, s = lib.cos(angle), lib.sin(angle)
    rows = {
        "x": [[1, 0, 0], [0, c, -s], [0, s, c]],
        "y": [[c, 0, s], [0, 1, 0], [-s, 0, c]],
        "z": [[c, -s, 0], [s, c, 0], [0, 0, 1]],
    }[axis]
    return _stack(lib, rows)


def _arm_points(q: Any, x_sh: Any, l1: float, l2: float) -> tuple[Any, ...]:
    """Elbow and hand positions and the four world joint axes of the arm (see arm_fk)."""
    lib = _lib(q, x_sh)
    q, x_sh = _vec(lib, q, 4, "arm.q"), _vec(lib, x_sh, 3, "arm.x_sh")
    down = _vec(lib, [0.0, 0.0, -1.0], 3, "down")
    r_abd = _rot(lib, "x", -q[1])
    r_flex = r_abd @ _rot(lib, "y", -q[0])
    r_sh = r_flex @ _rot(lib, "z", q[2])
    elbow = x_sh + l1 * (r_sh @ down)
    hand = elbow + l2 * (r_sh @ (_rot(lib, "y", -q[3]) @ down))
    e_x, e_y, e_z = (_vec(lib, np.eye(3)[i], 3, "axis") for i in range(3))
    axes = (-(r_abd @ e_y), -e_x, r_flex @ e_z, -(r_sh @ e_y))  # q1, q2, q3, q4
    return lib, elbow, hand, axes, x_sh


def arm_fk(q: Any, x_sh: Any, l1: float = UPPER_ARM, l2: float = FOREARM) -> Any:
    """Hand position x^H = FK(q, x^sh) of the 4-DoF human arm (Eq. 10, seed B §3.3).

    Frame: x forward (away from the person), y to the person's left, z up. At q = 0 the arm
    hangs straight down from the shoulder; it is a right arm. Joint order
    q = [q1, q2, q3, q4] (rad):

    * q1 shoulder flexion (> 0 swings the arm forward),
    * q2 shoulder abduction (> 0 lifts the arm sideways, towards -y),
    * q3 internal rotation about the upper-arm axis (> 0 turns a bent forearm towards +y),
    * q4 elbow flexion (> 0 bends the forearm forward; 0 = straight arm).

    The shoulder rotation is R = R_x(-q2) R_y(-q1) R_z(q3): abduction tilts the arm's plane
    about the forward axis, flexion acts inside that plane, internal rotation turns about the
    upper arm. The elbow turns about the upper arm's own -y axis, parallel to the flexion
    axis, so with q3 = 0 the arm is a planar two-link arm in the abducted plane.

    Args:
        q: joint angles (4,).
        x_sh: shoulder position x^sh (3,) [m].
        l1: upper-arm length [m].
        l2: forearm length, elbow to grip [m].

    Returns:
        Hand position (3,).
    """
    return _arm_points(q, x_sh, l1, l2)[2]


def arm_jacobian(q: Any, x_sh: Any, l1: float = UPPER_ARM, l2: float = FOREARM) -> Any:
    """J_H(q) = ∂x^H/∂q, (3, 4), of the arm of :func:`arm_fk` (Eq. 11, seed B §3.3).

    Column i is the joint axis crossed with the lever from the joint to the hand (all joints
    revolute), in closed form for numpy and casadi alike.
    """
    lib, elbow, hand, axes, x_sh = _arm_points(q, x_sh, l1, l2)
    origins = (x_sh, x_sh, x_sh, elbow)
    cols = [lib.cross(w, hand - o) for w, o in zip(axes, origins, strict=True)]
    return np.column_stack(cols) if lib is np else lib.horzcat(*cols)


def arm_ik(x_hand: Any, x_sh: Any, l1: float = UPPER_ARM, l2: float = FOREARM) -> Any:
    """Closed-form inverse of :func:`arm_fk` with q3 = 0 (seed B §3.3).

    Seed B assumes zero internal rotation, which leaves the planar two-link arm of
    :func:`arm_fk` in a plane tilted by abduction about the forward axis. With r = x^H − x^sh
    and d = ‖r‖:

    * elbow, law of cosines: cos q4 = (d² − l1² − l2²) / (2 l1 l2), q4 ∈ [0, π];
    * abduction turns the plane to contain r: q2 = atan2(−r_y, −r_z);
    * flexion aims the two-link arm at r in that plane: with in-plane hand (h_x, h_z) =
      (r_x, −√(r_y² + r_z²)) and the arm's own hand vector (a, −b) = (l2 sin q4,
      −(l1 + l2 cos q4)), q1 is the angle from (a, −b) to (h_x, h_z).

    Reach: the elbow angle is clipped to [1e-3, π − 1e-3] rad, i.e. a hand beyond l1 + l2
    (or closer than |l1 − l2|) is treated as the reachable point in the same direction,
    keeping acos's slope finite for casadi. Singular points: r on the forward axis
    (r_y = r_z = 0, the plane is undetermined) and the branch cut of q2 directly above the
    shoulder (r_y = 0, r_z > 0); co-manipulation with the hand below shoulder height
    avoids both.

    Args:
        x_hand: hand position (3,) [m]; a 2-D task pads its own z (e.g. table height).
        x_sh: shoulder position (3,) [m].

    Returns:
        q (4,) with q[2] = 0.
    """
    lib = _lib(x_hand, x_sh)
    r = _vec(lib, x_hand, 3, "arm.x_hand") - _vec(lib, x_sh, 3, "arm.x_sh")
    d2 = r[0] ** 2 + r[1] ** 2 + r[2] ** 2
    c4 = (d2 - l1**2 - l2**2) / (2.0 * l1 * l2)
    lo, hi = math.cos(math.pi - _ELBOW_EPS), math.cos(_ELBOW_EPS)
    q4 = lib.arccos(lib.fmin(lib.fmax(c4, lo), hi))
    q2 = lib.arctan2(-r[1], -r[2])
    h_x, h_z = r[0], -lib.sqrt(r[1] ** 2 + r[2] ** 2)
    a, b = l2 * lib.sin(q4), l1 + l2 * lib.cos(q4)
    q1 = lib.arctan2(a * h_z + b * h_x, a * h_x - b * h_z)
    return np.array([q1, q2, 0.0, q4]) if lib is np else lib.vertcat(q1, q2, 0.0, q4)


def joint_torque_cost(
    x_hand: Any, f_hand: Any, q_tau: Any, x_sh: Any, l1: float = UPPER_ARM, l2: float = FOREARM
) -> Any:
    """Ergonomic cost τ_Hᵀ Q_τ τ_H = f_Hᵀ J_H Q_τ J_Hᵀ f_H, with τ_H = J_Hᵀ f_H (Eq. 11, 15).

    The arm posture is q = :func:`arm_ik` (x_hand) with the hand at the robot TCP
    (x^H = x, seed B §3.3). What force f_H the human feels is the caller's choice: seed B's
    polishing task uses the robot's damping force along the expected motion, f_H = D ẋ
    (§4.2.2), which makes the cost depend on the damping being optimised.

    Args:
        x_hand: hand (TCP) position (3,); 2-D callers pad z.
        f_hand: force at the hand f_H (3,) [N]; 2-D callers pad 0.
        q_tau: Q_τ, a scalar, a diagonal (4,) or a (4, 4) matrix.
        x_sh: shoulder position (3,).

    Returns:
        The scalar cost [N² m²]: a float or a casadi scalar.
    """
    lib = _lib(x_hand, f_hand, q_tau, x_sh)
    jac = arm_jacobian(arm_ik(x_hand, x_sh, l1, l2), x_sh, l1, l2)
    tau = jac.T @ _vec(lib, f_hand, 3, "arm.f_hand")
    if lib is np or not isinstance(q_tau, lib.MX | lib.SX | lib.DM):
        q_tau = np.asarray(q_tau, dtype=float)
        if q_tau.shape in ((1,), (1, 1)):  # a scalar weight, element-wise below
            q_tau = q_tau.reshape(())
        elif q_tau.shape == (4, 1):
            q_tau = q_tau.reshape(4)
        q_tau = q_tau if lib is np else lib.DM(q_tau)
    shape = tuple(q_tau.shape)
    if shape in ((), (1,), (1, 1), (4,), (4, 1)):
        weighted = q_tau * tau  # a scalar or a diagonal, element-wise
    elif shape == (4, 4):
        weighted = q_tau @ tau
    else:
        raise ConfigError("arm.q_tau", f"must be a scalar, (4,) or (4, 4), got shape {shape}")
    out = tau.T @ weighted
    return float(out) if lib is np else out


def disturbance_state_space(
    mass: Any, damping: Any, stiffness: Any, alpha: float, omega_p: float
) -> tuple[Any, Any, Any]:
    """A state-space realisation (A_d, B_d, C_d) of X^d(s) = A(s) F^d(s) (seed B §4.2.3).

    F^d(s) = α s / (s + ω_p) and A(s) = 1 / (M s² + D s + K) for one DOF. With k = K/M,
    p = D/M the controllable canonical form of α/M · s / ((s + ω_p)(s² + p s + k)) has three
    states. For K = 0 (given as a number), the s of F^d cancels the admittance's integrator
    pole and the minimal form α/M / ((s + ω_p)(s + p)) has two. A symbolic K always gets the
    three-state form, whose A_d is singular at K = 0 (the Lyapunov solve then fails).
    """
    lib = _lib(mass, damping, stiffness)
    p, c = damping / mass, alpha / mass
    if _lib(stiffness) is not np or np.ndim(stiffness) != 0 or float(stiffness) != 0.0:
        k = stiffness / mass
        a0, a1, a2 = omega_p * k, omega_p * p + k, omega_p + p
        a = _stack(lib, [[0, 1, 0], [0, 0, 1], [-a0, -a1, -a2]])
        return a, _stack(lib, [[0], [0], [1]]), _stack(lib, [[0, c, 0]])
    a = _stack(lib, [[0, 1], [-omega_p * p, -(omega_p + p)]])
    return a, _stack(lib, [[0], [1]]), _stack(lib, [[c, 0]])


def h2_norm_sq(a: Any, b: Any, c: Any) -> Any:
    """‖C (sI − A)⁻¹ B‖²₂ = Bᵀ X_o B from the observability Gramian (Eq. 16-17, seed B).

    X_o solves the continuous-time Lyapunov equation Aᵀ X_o + X_o A + Cᵀ C = 0, so
    X_o = ∫₀^∞ e^{Aᵀt} Cᵀ C e^{At} dt and Bᵀ X_o B = ∫₀^∞ ‖C e^{At} B‖² dt, the energy of the
    impulse response. Seed B's printed Eq. 17, A_d X_o + X_o A_dᵀ = C_dᵀ C_d, puts the
    transposes of the controllability equation on the observability Gramian and flips the
    sign: for a stable A its solution is negative semidefinite (a negative "norm"), and it is
    not the observability Gramian unless A is symmetric. ccm implements the equation above.

    Solved by vectorising, (I ⊗ Aᵀ + Aᵀ ⊗ I) vec X_o = −vec(Cᵀ C) with column-major vec, which
    is fine for the 2-3 states here (seed B notes Bartels-Stewart for ill-conditioned cases).
    Works for numpy and casadi (differentiable through ``ca.solve``); A must be Hurwitz.
    """
    lib = _lib(a, b, c)
    n = a.shape[0]
    if lib is np:
        lhs = np.kron(np.eye(n), a.T) + np.kron(a.T, np.eye(n))
        x_o = np.linalg.solve(lhs, -(c.T @ c).reshape(-1, order="F")).reshape((n, n), order="F")
        return float((b.T @ x_o @ b).item())
    lhs = lib.kron(lib.DM.eye(n), a.T) + lib.kron(a.T, lib.DM.eye(n))
    x_o = lib.reshape(lib.solve(lhs, -lib.vec(c.T @ c)), n, n)
    return b.T @ x_o @ b


def disturbance_h2(
    mass: Any,
    damping: Any,
    stiffness: Any = 0.0,
    alpha: float = 1.0,
    omega_p: float = 2 * math.pi * 15,
    method: str = "closed_form",
) -> Any:
    """Disturbance-rejection cost ‖X^d‖²₂ for one DOF (Eq. 16-17, seed B §4.2.3).

    The position response X^d(s) = α s / ((s + ω_p)(M s² + D s + K)) to the high-pass
    disturbance force F^d(s) = α s / (s + ω_p); its squared H2 norm is the energy ∫ x^d(t)² dt
    of the response to an impulse (Parseval). For M, D, ω_p > 0 and K ≥ 0 it has the closed
    form (derived by ccm from the Gramian of :func:`disturbance_state_space`; the tests check
    it against the Lyapunov solution and the integrated impulse response)

        ‖X^d‖²₂ = α² / (2 D (M ω_p² + D ω_p + K)),

    which falls as M, D or K grow: more impedance, less disturbance motion. The K = 0 case
    is seed B's (§3.2 drops K). ``method="lyapunov"`` evaluates Eq. 16-17 instead, through
    :func:`h2_norm_sq` (needs K > 0 or a numeric K = 0).

    Args:
        mass: M_i [kg] > 0, a number or casadi symbol.
        damping: D_i [N s/m] > 0.
        stiffness: K_i [N/m] >= 0.
        alpha: disturbance magnitude α [N].
        omega_p: high-pass cut-off ω_p [rad/s] > 0.
        method: "closed_form" or "lyapunov".

    Returns:
        ‖X^d‖²₂ [m² s]: a float or a casadi scalar.
    """
    method = check_choice("mpc.disturbance.method", method, ("closed_form", "lyapunov"))
    if omega_p <= 0:
        raise ConfigError("mpc.disturbance.omega_p", f"must be > 0, got {omega_p!r}")
    if _lib(mass, damping, stiffness) is np:
        if mass <= 0 or damping <= 0:
            raise ConfigError("mpc.disturbance", f"needs M, D > 0, got M={mass}, D={damping}")
        check_nonneg("mpc.disturbance.stiffness", stiffness)
    if method == "lyapunov":
        return h2_norm_sq(*disturbance_state_space(mass, damping, stiffness, alpha, omega_p))
    return alpha**2 / (2.0 * damping * (mass * omega_p**2 + damping * omega_p + stiffness))


def belief_update(
    belief: Any, f: Any, means: Any, variances: Any, min_belief: float = 0.0
) -> np.ndarray:
    """One Bayes step of the mode belief, b_{t+1}[n] ∝ b_t[n] N(f_t; μ_n, Σ_n) (Eq. 12).

    μ_n, Σ_n = diag(variances[n]) are mode n's GP force mean and variance at the current pose.
    The Gaussian likelihood is det(2π Σ_n)^(−1/2) exp(−½ (f − μ_n)ᵀ Σ_n⁻¹ (f − μ_n)); seed B's
    printed Eq. 12 multiplies by det(2π Σ_n) and exponentiates +(f − μ_n)ᵀ Σ_n⁻¹ (f − μ_n),
    which would favour the mode that explains f worst; ccm reads it as a typo. The update runs
    in log space and is normalised with log-sum-exp, so large deviations do not underflow.

    ``min_belief`` is a ccm option (not in seed B): after the update every entry is raised to
    at least this floor and the rest rescaled to sum to 1, so a mode can regain belief when
    the human switches goals. 0 (default) is the pure Bayes update, where a mode that reaches
    belief 0 stays there.

    Args:
        belief: b_t (N,), a probability vector.
        f: measured force f_t (d,).
        means: μ_n for each mode (N, d).
        variances: diagonal of Σ_n for each mode (N, d), > 0.
        min_belief: floor in [0, 1/N].

    Returns:
        b_{t+1} (N,).
    """
    b = np.asarray(belief, dtype=float).reshape(-1)
    mu, var = np.atleast_2d(np.asarray(means, float)), np.atleast_2d(np.asarray(variances, float))
    f = np.asarray(f, dtype=float).reshape(-1)
    n_modes = b.size
    if n_modes == 0 or mu.shape != (n_modes, f.size) or var.shape != mu.shape:
        raise ConfigError(
            "mpc.belief",
            f"needs belief (N,), f (d,), means and variances (N, d); got {b.shape}, {f.shape},"
            f" {mu.shape}, {var.shape}",
        )
    if not (np.all(np.isfinite(f)) and np.all(np.isfinite(mu)) and np.all(np.isfinite(var))):
        raise ConfigError("mpc.belief", "f, means and variances must be finite")
    if np.any(var <= 0):
        raise ConfigError("mpc.belief.variances", f"must be > 0, got min {var.min()}")
    if not np.all(np.isfinite(b)) or np.any(b < 0) or abs(b.sum() - 1.0) > 1e-6:
        raise ConfigError("mpc.belief", f"must be a probability vector, got {b.tolist()}")
    if not 0.0 <= min_belief <= 1.0 / n_modes:
        raise ConfigError("mpc.belief.min_belief", f"must be in [0, 1/N], got {min_belief!r}")
    log_lik = -0.5 * np.sum(np.log(2 * np.pi * var) + (f - mu) ** 2 / var, axis=1)
    with np.errstate(divide="ignore"):
        log_post = np.log(b) + log_lik
    post = np.exp(log_post - log_post.max())
    post /= post.sum()
    if min_belief > 0.0:
        floored = np.zeros(n_modes, dtype=bool)
        while True:  # raise entries to the floor, rescale the rest; at most N passes
            free = post[~floored].sum()
            rest = 1.0 - min_belief * floored.sum()
            scaled = np.where(floored, min_belief, post * rest / free if free > 0 else 0.0)
            low = ~floored & (scaled < min_belief)
            if not low.any():
                return scaled
            floored |= low
    return post


def chance_quantile(epsilon: float, form: str = "normal", key: str = "mpc.chance") -> float:
    """The factor q of Prob{f ≤ f̄} ≥ 1 − ε ⇔ μ_f + q σ_f ≤ f̄ for f ~ N(μ_f, σ_f²) (Eq. 18).

    ``form="normal"`` (default) is the standard-normal quantile q = Φ⁻¹(1 − ε) =
    √2 erf⁻¹(1 − 2ε), which makes the equivalence exact. ``form="paper_erfinv"`` is
    q = erf⁻¹(1 − ε) as printed in seed B Eq. 18 (and used by its reference code). They differ:
    at seed B's ε = 0.5 (§6.1) the normal quantile is 0 (a 50 % constraint bounds the mean
    only) while erf⁻¹(0.5) ≈ 0.477; at ε = 0.05 they are 1.645 and 1.386 (the printed form
    then holds with ≈ 91.7 %, not 95 %).

    Args:
        epsilon: allowed violation probability ε in (0, 1).
        form: "normal" or "paper_erfinv".
        key: configuration-key prefix for errors.
    """
    form = check_choice(f"{key}.quantile", form, ("normal", "paper_erfinv"))
    eps = check_finite(f"{key}.epsilon", epsilon)
    if not 0.0 < eps < 1.0:
        raise ConfigError(f"{key}.epsilon", f"must be in (0, 1), got {epsilon!r}")
    if form == "normal":
        return NormalDist().inv_cdf(1.0 - eps)
    # erf⁻¹(y) = Φ⁻¹((1 + y)/2) / √2
    return NormalDist().inv_cdf(1.0 - eps / 2.0) / math.sqrt(2.0)


def chance_margin(
    mean: Any, variance: Any, upper: Any, epsilon: float, form: str = "normal"
) -> Any:
    """f̄ − μ_f − q √Σ_f, element-wise; ≥ 0 iff the chance constraint of Eq. 18 holds.

    Numpy or casadi (seed B applies it per linear force at the horizon's last point).
    """
    q = chance_quantile(epsilon, form)
    lib = _lib(mean, variance, upper)
    return upper - mean - q * lib.sqrt(variance)

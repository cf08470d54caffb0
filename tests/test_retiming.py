"""Eq. 10 blending, the Eq. 11 C∞ velocity profile (Fig. 3) and re-timing of patterns (§3.5)."""

from __future__ import annotations

import copy
import math
import warnings
from collections.abc import Callable
from typing import Any

import numpy as np
import pytest
from scipy.integrate import quad

from ccm.core.errors import ConfigError
from ccm.tasks.motion_pattern import MotionPattern
from ccm.tasks.retiming import RetimedPattern, TimeWarp
from ccm.tasks.smooth_step import (
    blend,
    blend_weight,
    profile_samples,
    smooth_step,
    smooth_step_derivs,
    smooth_step_integral,
)
from ccm.tasks.trajectory import build_pattern

# Largest |σ'''| on (0, 1) (at τ ≈ 0.135, from a 2·10⁶-point grid); σ⁗ and σ⁽⁵⁾ stay below
# 2.3e3 and 7.8e4. These bound the finite-difference errors below.
MAX_D3 = 110.6

SLOW = TimeWarp([(1.0, 2.0, 0.5), (3.0, 3.5, 1.0)])  # 1 → 0.5 → 1
SLOW_SWITCHES = (1.0, 2.0, 3.0, 3.5)


def _quad(f: Callable[[float], float], a: float, b: float, points: Any = None) -> float:
    """Adaptive Gauss–Kronrod (QUADPACK): an integrator independent of the module's table."""
    return quad(f, a, b, points=points, epsabs=1e-14, epsrel=1e-13, limit=500)[0]


def _gap(f: Callable[[Any], Any], x0: float, eps: float) -> float:
    """|f(x0 + eps) − f(x0 − eps)|: the difference of the one-sided values at distance eps."""
    return float(abs(f(x0 + eps) - f(x0 - eps)))


def line_pattern() -> MotionPattern:
    return build_pattern(
        [{"type": "line", "to": [0.3, 0.1], "duration": 2.0}], [0.0, 0.0], control_dt=0.001
    )


def line_force_pattern() -> MotionPattern:
    spec = [
        {"type": "line", "to": [0.2, 0.0], "duration": 1.5},
        {"type": "line", "to": [0.4, 0.0], "duration": 2.0, "force": {"direction": [0, -1],
                                                                       "magnitude": 5.0}},
    ]  # fmt: skip
    return build_pattern(spec, [0.0, 0.05], control_dt=0.001)


# --- σ (Eq. 11) --------------------------------------------------------------------------


def test_smooth_step_special_values() -> None:
    # exact: these follow from the stable form without rounding
    assert smooth_step(0.0) == 0.0
    assert smooth_step(1.0) == 1.0
    assert smooth_step(0.5) == 0.5
    assert smooth_step(-3.0) == 0.0
    assert smooth_step(7.0) == 1.0
    tau = np.linspace(0.0, 1.0, 10001)
    assert np.all(np.diff(smooth_step(tau)) >= 0.0)  # monotone (exact comparison)
    assert isinstance(smooth_step(0.3), float)
    assert smooth_step(np.zeros((2, 3))).shape == (2, 3)


def test_smooth_step_is_eq11_off_the_symmetric_points() -> None:
    """Eq. 11 (seed A) at tau = 1/4 and 9/10: e^(-1/tau) / (e^(-1/tau) + e^(-1/(1-tau))) =
    1 / (1 + e^(1/tau - 1/(1-tau))); 0.5 at tau = 1/2 would also hold for a swapped or squared
    exponent, these values do not."""
    for tau in (0.25, 0.9):
        expected = 1.0 / (1.0 + math.exp(1.0 / tau - 1.0 / (1.0 - tau)))
        assert smooth_step(tau) == pytest.approx(expected, rel=1e-14)
    assert smooth_step(0.25) == pytest.approx(0.06496, abs=1e-5)  # 1 / (1 + e^(8/3))


def test_smooth_step_symmetry() -> None:
    tau = np.linspace(-0.5, 1.5, 20001)
    s, d1, d2, d3 = smooth_step_derivs(tau)
    m, m1, m2, m3 = smooth_step_derivs(1.0 - tau)
    # σ(τ) + σ(1 − τ) = 1: rounding only (1 − τ is inexact in the last bit; |σ'| <= 2)
    np.testing.assert_allclose(s + m, 1.0, rtol=0, atol=1e-15)
    # derivatives of the identity: σ' even, σ'' odd, σ''' even about 1/2; allowance for
    # rounding in the 1/τ⁴ terms (observed: all exactly 0, since g(1 − τ) = −g(τ) in floats)
    np.testing.assert_allclose(d1, m1, rtol=0, atol=1e-13)
    np.testing.assert_allclose(d2, -m2, rtol=0, atol=1e-11)
    np.testing.assert_allclose(d3, m3, rtol=0, atol=1e-9)


# central-difference error ≤ h²/6 · max|σ^(order+2)| + eps · max|σ^(order-1)| / h with
# h = 1e-5: 1.8e-9, 3.8e-8 and 1.3e-6 (+ 2.4e-9 rounding); observed 1.8e-9, 3.8e-8, 1.3e-6
@pytest.mark.parametrize(("order", "tol"), [(1, 5e-9), (2, 1e-7), (3, 3e-6)])
def test_smooth_step_derivatives_match_finite_differences(order: int, tol: float) -> None:
    h = 1e-5
    tau = np.linspace(0.01, 0.99, 4001)
    lower = smooth_step_derivs(tau + h)[order - 1] - smooth_step_derivs(tau - h)[order - 1]
    fd = lower / (2 * h)
    exact = smooth_step_derivs(tau)[order]
    np.testing.assert_allclose(fd, exact, rtol=0, atol=tol)  # tolerance: see above
    # and the derivative is not trivially zero
    assert np.abs(exact).max() > 1.0


def test_smooth_step_is_safe_at_extremes() -> None:
    tau = np.array([5e-324, 1e-300, 1e-3, 1.0 - 1e-16, 1.0 - 1e-3, 1e300, -1e300, np.inf, -np.inf])
    with warnings.catch_warnings():
        warnings.simplefilter("error")  # any overflow/invalid RuntimeWarning fails the test
        out = np.array(smooth_step_derivs(tau))
    assert np.all(np.isfinite(out))
    np.testing.assert_array_equal(out[0], [0, 0, 0, 1, 1, 1, 0, 1, 0])  # exact
    with pytest.raises(ValueError, match="NaN"):
        smooth_step(np.nan)


def test_all_derivatives_vanish_at_both_ends() -> None:
    # C∞ joins: approaching 0 or 1 from inside, σ − σ(end) and every derivative → 0.
    for eps, tol in ((1e-3, 0.0), (1e-2, 1e-30), (2e-2, 1e-10)):
        # bounds: e^{−1/ε} · (1/ε²)³ · 7 with ε = 0.01 is ~1e-31; at 0.02, σ''' ≈ 7.4e-12
        # (at 1e-3 everything underflows to exactly 0)
        left = smooth_step_derivs(eps)
        right = smooth_step_derivs(1.0 - eps)
        assert max(abs(v) for v in left) <= tol
        assert max(abs(right[0] - 1.0), *(abs(v) for v in right[1:])) <= tol


def test_max_third_derivative_bounds_the_interpolation_error() -> None:
    # MAX_D3 enters the stated error bound of the S table: it must really bound |σ'''|
    d3 = smooth_step_derivs(np.linspace(0.0, 1.0, 200001))[3]
    assert 110.0 < np.abs(d3).max() <= MAX_D3  # grid step 5e-6: the peak is resolved to 1e-6


def test_smooth_step_integral_matches_adaptive_quadrature() -> None:
    tau = np.concatenate([np.linspace(0.0, 1.0, 41), [0.1234567, 0.5 + 1e-9, 0.999999]])
    ref = np.array([_quad(smooth_step, 0.0, t) for t in tau])
    # Hermite bound (1/2048)⁴/384 · MAX_D3 ≈ 1.6e-14 plus the reference's own error (asked
    # for 1e-14); observed 1e-14
    bound = (0.5 / 1024) ** 4 / 384 * MAX_D3
    np.testing.assert_allclose(smooth_step_integral(tau), ref, rtol=0, atol=bound + 1e-14)
    assert smooth_step_integral(0.0) == 0.0  # exact
    assert smooth_step_integral(1.0) == 0.5  # exact (symmetry)
    assert smooth_step_integral(2.5) == 2.0  # exact: τ − 1/2 beyond the blend
    assert smooth_step_integral(-1.0) == 0.0  # exact


# --- Fig. 3: v 1.2 → 0.5 in unit time -----------------------------------------------------


def test_fig3_endpoints_are_exact() -> None:
    tau, pos, vel, acc, jerk = profile_samples(1.2, 0.5, 101)
    assert tau[0] == 0.0 and tau[-1] == 1.0
    assert vel[0] == 1.2 and vel[-1] == 0.5  # exact
    assert acc[0] == 0.0 and acc[-1] == 0.0  # exact
    assert jerk[0] == 0.0 and jerk[-1] == 0.0  # exact
    assert pos[0] == 0.0  # exact
    # position at τ = 1 is (v1 + v2)/2 · T = 0.85 by symmetry; rounding only
    assert pos[-1] == pytest.approx(0.85, abs=1e-15)
    assert np.all(np.diff(vel) <= 0.0)  # monotone slow-down


def test_fig3_position_is_integrated_velocity() -> None:
    tau, pos, vel, _, _ = profile_samples(1.2, 0.5, 41, duration=1.0, margin=0.25)

    def v(t: float) -> float:
        return 1.2 + (0.5 - 1.2) * smooth_step(t)

    ref = np.array([_quad(v, 0.0, t, points=[0.0, 1.0] if t > 1.0 else None) for t in tau])
    np.testing.assert_allclose(vel, [v(t) for t in tau], rtol=0, atol=1e-15)  # same formula
    # issue target 1e-9; observed 4e-15 (table error × |v2 − v1| + the reference's error)
    np.testing.assert_allclose(pos, ref, rtol=0, atol=1e-12)


def test_fig3_acceleration_and_jerk_are_derivatives_in_time() -> None:
    T = 2.0
    tau, pos, vel, acc, jerk = profile_samples(1.2, 0.5, 2001, duration=T, margin=0.1)
    step = (tau[1] - tau[0]) * T  # sample spacing in time, 6e-4 s
    # central differences on neighbouring samples: error ≤ step²/6 · 0.7 · max|σ^(k+2)| / T^(k+1)
    # for order k: 6e-8 · (111/2, 2.3e3/4, 7.8e4/8) → 3e-6, 3e-5, 6e-4 (observed 4e-7, 2e-6, 2e-5)
    np.testing.assert_allclose(np.gradient(pos, step)[1:-1], vel[1:-1], rtol=0, atol=3e-6)
    np.testing.assert_allclose(np.gradient(vel, step)[1:-1], acc[1:-1], rtol=0, atol=3e-5)
    np.testing.assert_allclose(np.gradient(acc, step)[1:-1], jerk[1:-1], rtol=0, atol=6e-4)


def _profile_funcs(v1: float, v2: float) -> list[Callable[[float], float]]:
    def at(k: int) -> Callable[[float], float]:
        return lambda t: v1 * (k == 0) + (v2 - v1) * smooth_step_derivs(t)[k]

    return [at(0), at(1), at(2)]  # velocity, acceleration, jerk (T = 1)


@pytest.mark.parametrize("switch", [0.0, 1.0])
def test_fig3_velocity_acceleration_jerk_continuous_at_switches(switch: float) -> None:
    for name, f in zip(("velocity", "acceleration", "jerk"), _profile_funcs(1.2, 0.5), strict=True):
        # one-sided values 1e-2 from the switch differ by < 1e-30 (σ^(k)(0.01) ≤ 1e-31·|Δv|) and
        # 1e-3 from it by exactly 0: the one-sided limits agree
        assert _gap(f, switch, 1e-2) < 1e-30, name
        assert _gap(f, switch, 1e-3) == 0.0, name


def test_continuity_check_detects_the_linear_blend_kink() -> None:
    # The same one-sided check applied to Eq. 10's linear weight flags its derivative jump
    # (0 before, 1/T after): the continuity test above can fail.
    T = 0.5

    def d_alpha_linear(t: float) -> float:
        h = 1e-7
        return (blend_weight(t + h, 0.0, T) - blend_weight(t - h, 0.0, T)) / (2 * h)

    def d_alpha_smooth(t: float) -> float:
        h = 1e-7
        w1 = blend_weight(t + h, 0.0, T, "smooth")
        return (w1 - blend_weight(t - h, 0.0, T, "smooth")) / (2 * h)

    assert _gap(d_alpha_linear, 0.0, 1e-3) == pytest.approx(1.0 / T, rel=1e-6)  # FD rounding
    assert _gap(d_alpha_linear, T, 1e-3) == pytest.approx(1.0 / T, rel=1e-6)
    assert _gap(d_alpha_smooth, 0.0, 1e-3) == 0.0  # exact: both sides constant in floats
    assert _gap(d_alpha_smooth, T, 1e-3) == 0.0


# --- Eq. 10 blending ----------------------------------------------------------------------


def test_blend_weight_linear_is_eq10() -> None:
    assert blend_weight(2.0, 2.0, 0.4) == 0.0  # exact
    assert blend_weight(2.4, 2.0, 0.4) == 1.0  # exact, though (2.4 − 2) / 0.4 rounds below 1
    assert blend_weight(1.0, 2.0, 0.4) == 0.0  # exact: clipped before
    assert blend_weight(9.0, 2.0, 0.4) == 1.0  # exact: clipped after
    assert blend_weight(2.1, 2.0, 0.4) == pytest.approx(0.25, abs=1e-15)  # rounding
    t = np.linspace(1.0, 3.0, 201)
    np.testing.assert_allclose(
        blend_weight(t, 2.0, 0.4), np.clip((t - 2.0) / 0.4, 0, 1), rtol=0, atol=0
    )  # same formula: exact
    u1, u2 = np.array([1.0, -2.0, 3.0]), np.array([0.5, 4.0, -1.0])
    np.testing.assert_array_equal(blend(u1, u2, 0.0), u1)  # exact endpoints
    np.testing.assert_array_equal(blend(u1, u2, 1.0), u2)
    np.testing.assert_allclose(blend(u1, u2, 0.25), 0.75 * u1 + 0.25 * u2, rtol=0, atol=1e-15)


def test_blend_weight_smooth_option() -> None:
    t = np.linspace(-1.0, 2.0, 3001)
    arr = blend_weight(t, 0.0, 1.0, "smooth")
    scal = np.array([blend_weight(float(x), 0.0, 1.0, "smooth") for x in t])
    np.testing.assert_allclose(arr, smooth_step(t), rtol=0, atol=0)  # same path: exact
    np.testing.assert_allclose(scal, arr, rtol=0, atol=1e-15)  # scalar vs numpy exp rounding
    assert blend_weight(1.0, 0.0, 1.0, "smooth") == 1.0  # exact: the switch is complete at T


@pytest.mark.parametrize(
    ("kwargs", "key"),
    [
        ({"duration": 0.0}, "duration"),
        ({"duration": -1.0}, "duration"),
        ({"duration": math.nan}, "duration"),
        ({"shape": "cubic"}, "shape"),
    ],
)
def test_blend_weight_bad_arguments(kwargs: dict[str, Any], key: str) -> None:
    args: dict[str, Any] = {"t": 0.1, "t_start": 0.0, "duration": 1.0, **kwargs}
    with pytest.raises(ConfigError) as err:
        blend_weight(**args)
    assert err.value.key == key


def test_profile_samples_bad_arguments() -> None:
    for kwargs, key in (({"n": 1}, "n"), ({"duration": 0.0}, "duration"), ({"v1": "x"}, "v1")):
        args: dict[str, Any] = {"v1": 1.2, "v2": 0.5, "n": 10, **kwargs}
        with pytest.raises(ConfigError) as err:
            profile_samples(**args)
        assert err.value.key == key


# --- TimeWarp -----------------------------------------------------------------------------


def test_rate_one_warp_is_identity() -> None:
    w = TimeWarp()
    t = np.linspace(-1.0, 10.0, 1101)
    phi, rho, d1, d2, d3 = w.evaluate(t)
    np.testing.assert_array_equal(phi, t)  # exact
    np.testing.assert_array_equal(rho, 1.0)
    assert np.all(d1 == 0.0) and np.all(d2 == 0.0) and np.all(d3 == 0.0)
    assert w.phi(3.7) == 3.7 and w.inverse(3.7) == 3.7  # exact
    # a change to the same rate is also the identity (Δr = 0)
    np.testing.assert_array_equal(TimeWarp([(1.0, 2.0, 1.0)]).evaluate(t)[0], t)


def test_warp_starts_at_zero_and_is_monotone() -> None:
    t = np.linspace(0.0, 6.0, 60001)
    phi, rho, _, _, _ = SLOW.evaluate(t)
    assert phi[0] == 0.0  # exact
    assert SLOW.phi(0.0) == 0.0
    assert np.all(np.diff(phi) > 0.0)  # strictly increasing (exact comparison)
    assert rho.min() == 0.5 and rho.max() == 1.0  # exact levels
    # rate levels: 1 before, 0.5 in between, 1 after (exact)
    assert SLOW.rate(0.5) == 1.0 and SLOW.rate(2.5) == 0.5 and SLOW.rate(5.0) == 1.0


def test_warp_phi_is_the_integral_of_the_rate() -> None:
    ts = np.linspace(0.0, 5.0, 51)
    ref = [_quad(SLOW.rate, 0.0, t, points=[p for p in SLOW_SWITCHES if p < t] or None) for t in ts]
    # table error × T × |Δr| < 1e-14 per blend, plus the reference's error; observed 4e-15
    np.testing.assert_allclose(SLOW.phi(ts), ref, rtol=0, atol=1e-12)
    # closed forms at the ends of the blends: φ(2) = 1 + (1 + 0.5)/2, φ(3.5) = 2.25 + 0.375
    assert SLOW.phi(2.0) == 1.75 and SLOW.phi(3.5) == 2.625  # exact (S(1) = 1/2)


def test_warp_derivatives_match_finite_differences() -> None:
    t = np.linspace(0.5, 4.0, 3501)
    h = 1e-5
    lo, hi, exact = SLOW.evaluate(t - h), SLOW.evaluate(t + h), SLOW.evaluate(t)
    # truncation h²/6 · |Δr| · max|σ^(k+1)| / T^(k+1) for the ρ^(k) check (T >= 0.5, |Δr| = 0.5)
    # plus φ's table error 1e-14 / h on the φ' check; observed 3e-10, 7e-9, 3e-7, 2e-5
    for k, tol in ((0, 1e-8), (1, 1e-7), (2, 1e-5), (3, 1e-3)):
        fd = (hi[k] - lo[k]) / (2 * h)
        np.testing.assert_allclose(fd, exact[k + 1], rtol=0, atol=tol, err_msg=f"order {k + 1}")


@pytest.mark.parametrize("switch", SLOW_SWITCHES)
def test_warp_continuous_at_switches(switch: float) -> None:
    for k, name in enumerate(("phi", "rho", "rho'", "rho''")):

        def f(x: float, k: int = k) -> float:
            return SLOW.state(x)[k]

        # φ: Lipschitz (ρ ≤ 1) → gap ≤ 2ε + rounding; ρ, ρ', ρ'': gap below 1e-20 at ε = 5e-3
        # (σ^(k) at 0.01 ≤ 1e-31, T ≥ 0.5 ⇒ ≤ 1e-31 · 2³) and exactly 0 at ε = 1e-4
        if k == 0:
            assert _gap(f, switch, 1e-9) <= 2e-9 + 1e-15, name
        else:
            assert _gap(f, switch, 5e-3) < 1e-20, name
            assert _gap(f, switch, 1e-4) == 0.0, name


def test_warp_scalar_and_vector_paths_agree() -> None:
    t = np.linspace(-0.5, 5.0, 5501)
    vec = SLOW.evaluate(t)
    scal = np.array([SLOW.state(float(x)) for x in t]).T
    for k, tol in ((0, 0.0), (1, 1e-15), (2, 1e-14), (3, 1e-12)):
        # math.exp vs np.exp may differ in the last bit, scaled by 1/τ⁴ terms (≤ 111 · 8)
        np.testing.assert_allclose(scal[k], vec[k], rtol=0, atol=tol)


def test_warp_inverse_round_trip() -> None:
    warps = (
        SLOW,
        TimeWarp([(0.0, 0.3, 3.0), (0.3, 0.4, 0.01)]),
        TimeWarp.for_speed(1.2, 0.5, 0, 1),
    )
    for w in warps:
        for t in np.linspace(0.0, 6.0, 601):
            # Newton to machine precision; φ error ≤ 1e-14 divided by ρ ≥ 0.01 → 1e-12
            assert w.inverse(w.phi(float(t))) == pytest.approx(t, abs=1e-12)


def test_for_speed_schedule() -> None:
    w = TimeWarp.for_speed(v_plan=0.2, v_new=0.05, phi_start=0.5, phi_reach=1.0, hold=0.3)
    (t0, t1, r), (t2, t3, r_back) = w.changes
    assert (t0, r, r_back) == (0.5, 0.25, 1.0)  # exact: ρ = v_new / v_plan
    assert t1 == pytest.approx(0.5 + 2 * 0.5 / 1.25, abs=1e-15)  # rounding
    # the slow-down is complete exactly when the pattern reaches phi_reach (p_c); rounding only
    assert w.phi(t1) == pytest.approx(1.0, abs=1e-15)
    assert t2 == pytest.approx(t1 + 0.3, abs=1e-15)
    assert t3 - t2 == pytest.approx(t1 - t0, abs=1e-15)  # default return duration
    assert w.rate(t1 + 0.1) == 0.25 and w.rate(t3 + 1e-3) == 1.0  # exact levels
    keep = TimeWarp.for_speed(0.2, 0.05, 0.5, 1.0)  # hold=None: stay slow
    assert len(keep.changes) == 1 and keep.final_rate == 0.25
    back = keep.extended(2.0, 2.2, 1.0)
    assert back.changes[1] == (2.0, 2.2, 1.0) and back.final_rate == 1.0
    assert back.phi(1.9) == keep.phi(1.9)  # exact: appending leaves the past unchanged


@pytest.mark.parametrize(
    ("changes", "kwargs", "key"),
    [
        ([(1.0, 2.0, 0.5), (1.5, 3.0, 1.0)], {}, "time_warp.changes[1].t_start"),
        ([(1.0, 1.0, 0.5)], {}, "time_warp.changes[0].t_end"),
        ([(1.0, 0.5, 0.5)], {}, "time_warp.changes[0].t_end"),
        ([(1.0, 2.0, 0.0)], {}, "time_warp.changes[0].rate_after"),
        ([(1.0, 2.0, -1.0)], {}, "time_warp.changes[0].rate_after"),
        ([(math.nan, 2.0, 0.5)], {}, "time_warp.changes[0].t_start"),
        ([(-1.0, 2.0, 0.5)], {}, "time_warp.changes[0].t_start"),
        ([(1.0, math.inf, 0.5)], {}, "time_warp.changes[0].t_end"),
        ([(1.0, 2.0)], {}, "time_warp.changes[0]"),
        ([{"t_start": 1.0, "t_end": 2.0}], {}, "time_warp.changes[0]"),
        ("abc", {}, "time_warp.changes"),
        ([], {"rate0": 0.0}, "time_warp.rate0"),
    ],
)
def test_warp_bad_arguments(changes: Any, kwargs: dict[str, Any], key: str) -> None:
    with pytest.raises(ConfigError) as err:
        TimeWarp(changes, **kwargs)
    assert err.value.key == key and len(str(err.value).splitlines()) == 1


def test_extended_rejects_an_overlapping_change_with_the_warps_key() -> None:
    with pytest.raises(ConfigError) as err:
        TimeWarp([(1.0, 2.0, 0.5)], key="task.warp").extended(1.5, 2.5, 1.0)
    assert err.value.key == "task.warp.changes[1].t_start"


def test_warp_accepts_mappings() -> None:
    w = TimeWarp([{"t_start": 1.0, "t_end": 2.0, "rate_after": 0.5}])
    assert w.changes == ((1.0, 2.0, 0.5),)


@pytest.mark.parametrize(
    ("kwargs", "key"),
    [
        ({"v_plan": 0.0}, "time_warp.v_plan"),
        ({"v_new": -0.1}, "time_warp.v_new"),
        ({"phi_reach": 0.5}, "time_warp.phi_reach"),
        ({"phi_start": -0.1}, "time_warp.phi_start"),
        ({"hold": -1.0}, "time_warp.hold"),
        ({"hold": 0.1, "return_duration": 0.0}, "time_warp.return_duration"),
    ],
)
def test_for_speed_bad_arguments(kwargs: dict[str, Any], key: str) -> None:
    args: dict[str, Any] = {"v_plan": 0.2, "v_new": 0.05, "phi_start": 0.5, "phi_reach": 1.0}
    with pytest.raises(ConfigError) as err:
        TimeWarp.for_speed(**{**args, **kwargs})
    assert err.value.key == key


# --- RetimedPattern -----------------------------------------------------------------------


def test_retimed_identity_is_the_pattern() -> None:
    p = line_force_pattern()
    rp = RetimedPattern(p, TimeWarp())
    assert rp.duration == p.duration  # exact
    for t in np.linspace(-0.5, p.duration + 0.5, 401):
        a, b = rp.sample(float(t)), p.sample(float(t))
        np.testing.assert_array_equal(a.position, b.position)  # exact: same evaluation
        np.testing.assert_array_equal(a.velocity, b.velocity)
        np.testing.assert_array_equal(a.acceleration, b.acceleration)
        assert (a.segment, a.done, a.force_mag, a.t) == (b.segment, b.done, b.force_mag, b.t)


def test_retimed_line_ends_exactly_at_the_pattern_end() -> None:
    p = line_pattern()
    w = TimeWarp.for_speed(v_plan=0.2, v_new=0.05, phi_start=0.5, phi_reach=1.0, hold=0.3)
    rp = RetimedPattern(p, w)
    (t0, t1, r), (t2, t3, _) = w.changes
    # progress lost to the slow-down: (1 − r)(T_in/2 + hold + T_out/2); rounding only
    lost = (1 - r) * ((t1 - t0) / 2 + (t2 - t1) + (t3 - t2) / 2)
    assert rp.duration == pytest.approx(p.duration + lost, abs=1e-13)
    assert w.phi(rp.duration) == pytest.approx(p.duration, abs=1e-14)  # Newton inverse
    end = rp.sample(rp.duration)
    np.testing.assert_array_equal(end.position, p.end)  # exact
    np.testing.assert_array_equal(end.velocity, 0.0)  # exact
    assert end.done and not rp.sample(rp.duration - 1e-6).done
    # approaching the end: min-jerk stop, position within (1e-6 s)³-scale of the end
    np.testing.assert_allclose(rp.sample(rp.duration - 1e-6).position, p.end, rtol=0, atol=1e-15)
    assert rp.sample(rp.duration + 5.0).t == rp.duration + 5.0


def test_retimed_velocity_is_pattern_velocity_times_rate() -> None:
    p = line_pattern()
    rp = RetimedPattern(p, TimeWarp.for_speed(0.2, 0.05, 0.5, 1.0, hold=0.3))
    for t in np.linspace(0.0, rp.duration, 301):
        phi, rho, drho, _ = rp.warp.state(float(t))
        s, base = rp.sample(float(t)), p.sample(phi)
        np.testing.assert_array_equal(s.position, base.position)  # exact: P(φ)
        np.testing.assert_allclose(s.velocity, base.velocity * rho, rtol=0, atol=1e-17)
        acc = base.acceleration * rho**2 + base.velocity * drho
        np.testing.assert_allclose(s.acceleration, acc, rtol=0, atol=1e-16)
    # in the hold the speed is v_new where the plan moves at v_plan: ratio exactly ρ = 0.25
    t_hold = rp.warp.changes[0][1] + 0.1
    speed = np.linalg.norm(rp.sample(t_hold).velocity)
    plan = np.linalg.norm(p.sample(rp.warp.phi(t_hold)).velocity)
    assert speed == pytest.approx(0.25 * plan, rel=1e-14)


def test_retimed_derivatives_match_finite_differences() -> None:
    p = line_force_pattern()
    rp = RetimedPattern(p, TimeWarp([(0.4, 1.0, 0.3), (1.6, 2.5, 1.5)]))
    h = 1e-5
    for t in np.linspace(0.01, rp.duration - 0.01, 700):
        # copies: the pattern reuses its sample (issue #40)
        lo, mid, hi = (copy.deepcopy(rp.sample(float(t + d))) for d in (-h, 0.0, h))
        # truncation h²/6 · |jerk| (≤ ~5 m/s³ → 1e-10) plus φ error 1e-14 · |P'| / h and
        # rounding eps · 0.4 m / h ≈ 1e-11; observed 2e-10
        np.testing.assert_allclose((hi.position - lo.position) / (2 * h), mid.velocity, atol=1e-8)
        # one more order: ≤ h²/6 · |snap| + eps · |v| / h; observed 2e-9
        np.testing.assert_allclose(
            (hi.velocity - lo.velocity) / (2 * h), mid.acceleration, atol=1e-7
        )


def test_retimed_force_targets_follow_the_pattern() -> None:
    p = line_force_pattern()
    rp = RetimedPattern(p, TimeWarp([(0.5, 1.0, 0.4)]))
    seen = set()
    for t in np.linspace(0.0, rp.duration + 0.2, 500):
        s = rp.sample(float(t))
        base = p.sample(min(rp.warp.phi(float(t)), p.duration))
        assert s.t == float(t)
        assert s.segment == base.segment and s.force_mag == base.force_mag  # exact
        assert (s.force_dir is None) == (base.force_dir is None)
        seen.add(s.segment)
    assert seen == {0, 1}
    # the force segment starts at pattern time 1.5, i.e. later in wall time
    assert rp.sample(1.6).segment == 0 and p.sample(1.6).segment == 1


def test_sample_many_matches_sample() -> None:
    p = line_force_pattern()
    rp = RetimedPattern(p, TimeWarp([(0.5, 1.0, 0.4), (2.0, 3.0, 1.2)]))
    ts = np.linspace(-0.2, rp.duration + 0.3, 777)
    many = rp.sample_many(ts)
    for i, t in enumerate(ts):
        s = rp.sample(float(t))
        # scalar math vs numpy paths: rounding in φ and ρ' only
        np.testing.assert_allclose(many["position"][i], s.position, rtol=0, atol=1e-15)
        np.testing.assert_allclose(many["velocity"][i], s.velocity, rtol=0, atol=1e-15)
        np.testing.assert_allclose(many["acceleration"][i], s.acceleration, rtol=0, atol=1e-13)
        assert many["done"][i] == s.done and many["segment"][i] == s.segment
    np.testing.assert_array_equal(many["position"][-1], p.end)  # exact

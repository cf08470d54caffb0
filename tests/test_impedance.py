"""Unit tests of the fixed impedance law (Eq. 1, seed A) without a simulator."""

from __future__ import annotations

import numpy as np
import pytest

from ccm.control.impedance import FixedImpedance
from ccm.control.loop import HybridLoop, damping_from_rule, impedance_term
from ccm.control.registry import make_controller
from ccm.core.errors import ConfigError
from ccm.core.types import Observation, TargetSample


def obs(pos=(0.0, 0.0), vel=(0.0, 0.0), force=(0.0, 0.0)) -> Observation:
    return Observation(
        t=0.0,
        position=np.array(pos, float),
        orientation=np.zeros(1),
        lin_vel=np.array(vel, float),
        ang_vel=np.zeros(1),
        force=np.array(force, float),
        torque=np.zeros(1),
    )


def target(pos=(0.0, 0.0), vel=(0.0, 0.0), acc=(0.0, 0.0), fdir=None, fmag=0.0) -> TargetSample:
    return TargetSample(
        t=0.0,
        position=np.array(pos, float),
        velocity=np.array(vel, float),
        acceleration=np.array(acc, float),
        orientation=np.zeros(1),
        force_dir=None if fdir is None else np.array(fdir, float),
        force_mag=fmag,
    )


def make(stiffness: float | list[float] = 300.0, **loop) -> FixedImpedance:
    """A reset controller; keyword arguments other than the stiffness go to its loop block."""
    c = FixedImpedance(stiffness=stiffness, loop=loop)
    c.reset(2, 0.001)
    return c


def test_spring_damper_law() -> None:
    c = make(stiffness=100.0, damping_rule="fixed", damping=10.0, inertia_feedforward=False)
    u = c.step(obs(pos=(0.01, -0.02), vel=(0.1, 0.0)), target())
    np.testing.assert_allclose(u.force, [100 * -0.01 + 10 * -0.1, 100 * 0.02], rtol=1e-12)


def test_per_axis_stiffness_and_inertial_feedforward() -> None:
    c = make(stiffness=[100.0, 400.0], damping_rule="fixed", damping=0.0, mass_kg=2.0)
    u = c.step(obs(pos=(0.01, 0.01)), target(acc=(1.0, -1.0)))
    np.testing.assert_allclose(u.force, [-1.0 + 2.0, -4.0 - 2.0], rtol=1e-12)


def test_damping_rules() -> None:
    assert damping_from_rule(400.0, "critical", 1.0, 1.0, 0.0) == pytest.approx(40.0)
    assert damping_from_rule(400.0, "paper", 1.0, 1.0, 0.0) == pytest.approx(5.0)
    assert damping_from_rule(400.0, "fixed", 1.0, 1.0, 7.0) == pytest.approx(7.0)


def test_force_direction_replaces_position_control() -> None:
    """Along d the law regulates force; position error along d is ignored."""
    c = make(
        stiffness=1000.0, force_kp=0.0, force_ki=0.0, force_damping=0.0, inertia_feedforward=False
    )
    # 5 cm position error along -y (the force direction) must not produce any force.
    u = c.step(obs(pos=(0.0, 0.05)), target(fdir=(0.0, -1.0), fmag=10.0))
    np.testing.assert_allclose(u.force, [0.0, -10.0], atol=1e-12)


def test_force_feedback_sign() -> None:
    """In contact the sensor reads +y when pushing down; too little push -> push harder."""
    c = make(force_kp=1.0, force_ki=0.0, force_damping=0.0, inertia_feedforward=False)
    weak = c.step(obs(force=(0.0, 4.0)), target(fdir=(0.0, -1.0), fmag=10.0))
    strong = c.step(obs(force=(0.0, 16.0)), target(fdir=(0.0, -1.0), fmag=10.0))
    assert weak.force[1] < -10.0 < strong.force[1]
    assert c.signals()["force_error_N"] == pytest.approx(-6.0)


@pytest.mark.parametrize(
    ("kwargs", "key"),
    [
        ({"stiffness": -1.0}, "controller.stiffness"),
        ({"stiffness": float("nan")}, "controller.stiffness"),
        ({"loop": {"damping_rule": "magic"}}, "controller.loop.damping_rule"),
        ({"loop": {"force_kp": -0.1}}, "controller.loop.force_kp"),
        ({"loop": {"mass_kg": 0.0}}, "controller.loop.mass_kg"),
    ],
)
def test_bad_gains_name_the_key(kwargs: dict, key: str) -> None:
    with pytest.raises(ConfigError) as err:
        FixedImpedance(**kwargs)
    assert err.value.key == key
    assert "\n" not in str(err.value)


def test_registry_rejects_unknown_type_and_key() -> None:
    with pytest.raises(ConfigError, match="controller.type"):
        make_controller({"type": "nope"})
    with pytest.raises(ConfigError, match="controller.stifness"):
        make_controller({"type": "fixed_impedance", "stifness": 10.0})


def test_loop_keys_belong_in_the_loop_block() -> None:
    """A force-loop gain at the controller's top level, or a gain in the loop block that the
    loop does not have, is refused with the key it was given under."""
    with pytest.raises(ConfigError, match=r"^controller.force_kp: unknown key"):
        make_controller({"type": "fixed_impedance", "force_kp": 0.5})
    with pytest.raises(ConfigError, match=r"^controller.loop.stiffness: unknown key"):
        make_controller({"type": "fixed_impedance", "loop": {"stiffness": 1.0}})


def test_stiffness_dimension_checked_at_reset() -> None:
    c = FixedImpedance(stiffness=[1.0, 2.0, 3.0])
    with pytest.raises(ConfigError, match="controller.stiffness"):
        c.reset(2, 0.001)


@pytest.mark.parametrize("dim", [2, 3])
@pytest.mark.parametrize("per_axis", [False, True])
@pytest.mark.parametrize("feedforward", [False, True])
def test_impedance_kernel_is_bit_identical_to_numpy(
    dim: int, per_axis: bool, feedforward: bool
) -> None:
    """The compiled motion term (scalar or per-axis gains) equals the numpy reference bit for
    bit; a gain the kernel does not take (length 1) still goes through numpy."""
    rng = np.random.default_rng(dim)
    r = 1 if dim == 2 else 3
    for _ in range(200):
        obs = Observation(0.0, *(rng.normal(size=k) for k in (dim, r, dim, r, dim, r)))
        target = TargetSample(0.0, *(rng.normal(size=k) for k in (dim, dim, dim, r)))
        kp = rng.uniform(1, 3000, size=dim) if per_axis else float(rng.uniform(1, 3000))
        kd = rng.uniform(0, 100, size=dim) if per_axis else float(rng.uniform(0, 100))
        got = impedance_term(obs, target, kp, kd, 1.3, feedforward)
        ref = impedance_term(obs, target, kp, kd, 1.3, feedforward, compiled=False)
        np.testing.assert_array_equal(got, ref)
    one = np.array([500.0])
    np.testing.assert_array_equal(
        impedance_term(obs, target, one, one, 1.3, feedforward),
        impedance_term(obs, target, one, one, 1.3, feedforward, compiled=False),
    )


@pytest.mark.parametrize("per_axis", [False, True])
@pytest.mark.parametrize("feedforward", [False, True])
def test_impedance_matrix_kernel_matches_numpy(per_axis: bool, feedforward: bool) -> None:
    """With Λ (3, 3) and the critical rule's K_d matrix (the 3-D arm), the compiled motion term
    equals the numpy lines to rounding (the products' sums in another order), and K_d for a
    scalar K_p equals K_d for that K_p on every axis bit for bit."""
    rng = np.random.default_rng(11)
    loop = HybridLoop()
    for _ in range(200):
        obs = Observation(0.0, *(rng.normal(size=3) for _ in range(6)))
        target = TargetSample(0.0, *(rng.normal(size=3) for _ in range(4)))
        a = rng.normal(size=(3, 3))
        lam = a @ a.T + np.eye(3)  # symmetric positive definite, kg
        k = float(rng.uniform(1, 3000))
        kp = rng.uniform(1, 3000, size=3) if per_axis else k
        kd = loop.damping_for(kp, lam)
        if not per_axis:
            np.testing.assert_array_equal(kd, loop.damping_for(np.full(3, k), lam))
        got = impedance_term(obs, target, kp, kd, lam, feedforward)
        ref = impedance_term(obs, target, kp, kd, lam, feedforward, compiled=False)
        np.testing.assert_allclose(got, ref, rtol=1e-12, atol=1e-9)


@pytest.mark.parametrize("n", [2, 3, 6])
def test_symmetric_root_squares_to_the_matrix(n: int) -> None:
    """Λ^½ by Jacobi rotations (the critical rule's kernel) is symmetric, squares back to Λ and
    equals the eigendecomposition's root, for well- and ill-conditioned Λ and a diagonal one."""
    from ccm.control._impedance_kernels import _symmetric_root

    rng = np.random.default_rng(n)
    cases = [np.diag(rng.uniform(0.5, 5.0, n))]
    for cond in (1.0, 1e3, 1e7):
        q, _ = np.linalg.qr(rng.normal(size=(n, n)))
        cases.append((q * np.geomspace(1.0, 1.0 / cond, n)) @ q.T * 8.0)
    for lam in cases:
        root = _symmetric_root(lam)
        m, v = np.linalg.eigh(lam)
        np.testing.assert_allclose(root, root.T, atol=1e-14 * np.abs(root).max())
        np.testing.assert_allclose(root @ root, lam, atol=1e-12 * np.abs(lam).max())
        np.testing.assert_allclose(root, (v * np.sqrt(m)) @ v.T, atol=1e-10 * np.abs(root).max())

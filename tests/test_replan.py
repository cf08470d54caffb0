"""The anticipating controller's plan around expected contacts, by hand (seed A §3.5,
Eq. 10-11; :mod:`ccm.control.adaptive.replan`).

A collision pass must slow the target so that the slow-down is complete where the path
reaches C (Eq. 10: the switch is complete on reaching C) and speed up only where C ends;
its transition window rises over ``blend_s`` to t_c, the time the (re-timed) path reaches
p_c. These tests give the functions passes with known φ and a warp with a known inverse.
"""

from __future__ import annotations

import numpy as np
import pytest

from ccm.control.adaptive.contact_events import TransitionWindow
from ccm.control.adaptive.replan import rate_changes, windows_ahead
from ccm.tasks.retiming import TimeWarp


def _assert_windows(windows: list[TransitionWindow], expected: list[tuple]) -> None:
    assert [(w.contact, w.kind) for w in windows] == [e[:2] for e in expected]
    np.testing.assert_allclose(
        [(w.t0, w.t1, w.release) for w in windows], [e[2:] for e in expected], atol=1e-12
    )


def test_windows_ahead_of_a_half_speed_plan() -> None:
    """ρ = 0.5, so the path reaches φ at t = 2φ. From t = 0.6 (φ = 0.3), blend 0.5 s:
    a pass ahead rises over [t_c − 0.5, t_c] (clipped at now); a pass whose C holds φ = 0.3
    starts at once; passes behind, made (``hits``) or crossings already begun get none."""
    warp = TimeWarp([], rate0=0.5)
    slow = [
        (0, 1.0, 1.5, []),  # ahead: t_c = 2.0, rises from 1.5, releases at 3.0
        (1, 0.3, 0.8, []),  # C begins exactly here: inside now
        (2, 0.1, 0.3, []),  # C ended exactly here: behind
        (3, 2.0, 2.5, []),  # made already
        (6, 0.5, 0.9, []),  # ahead, but t_c − blend = 0.5 < now: rises from now
    ]
    crossings = [(4, 1.2, 1.4), (5, 0.3, 0.5)]  # 5 begins exactly here: not ahead
    got = windows_ahead(slow, crossings, {3}, warp, t_from=0.6, phi_from=0.3, blend_s=0.5)
    _assert_windows(got, [
        (0, "collision", 1.5, 2.0 + 1e-9, 3.0),
        (1, "collision", 0.6, 0.6 + 1e-9, 1.6),
        (6, "collision", 0.6, 1.0 + 1e-9, 1.8),
        (4, "impactless", 1.9, 2.4, 2.8),
    ])  # fmt: skip


def test_rate_changes_complete_the_slow_down_where_c_begins() -> None:
    """One collision pass with a speed-limit piece ρ = 0.5 over φ ∈ [1, 2) on an unwarped
    plan, blend 0.4 s. The slow-down covers 0.5 (1 + 0.5) 0.4 = 0.3 of φ and ends at φ = 1
    (t = 1.1 after starting at t = φ = 0.7); the speed-up starts where the piece ends,
    φ = 2: 0.9 s later at half speed, t = 3.1."""
    changes: list = []
    slow = [(0, 1.0, 2.0, [(1.0, 2.0, 0.5)])]
    warp, rate0 = rate_changes(changes, TimeWarp(), 1.0, slow, set(), 0.0, 0.0, 0.4)
    assert rate0 == 1.0
    np.testing.assert_allclose(changes, [(0.7, 1.1, 0.5), (3.1, 3.5, 1.0)], atol=1e-9)
    assert float(warp.phi(1.1)) == pytest.approx(1.0, abs=1e-9)
    assert float(warp.phi(3.1)) == pytest.approx(2.0, abs=1e-9)
    made: list = []
    rate_changes(made, TimeWarp(), 1.0, slow, {0}, 0.0, 0.0, 0.4)
    assert made == []  # a contact already made needs no limit


def test_rate_changes_of_a_plan_that_starts_inside_c() -> None:
    """A piece from φ = 0: the initial rate becomes ρ = 0.5 (no blend before t = 0), and the
    speed-up starts where the piece ends, φ = 1 at t = 2."""
    changes: list = []
    slow = [(0, 0.0, 1.0, [(0.0, 1.0, 0.5)])]
    warp, rate0 = rate_changes(changes, TimeWarp(), 1.0, slow, set(), 0.0, 0.0, 0.4)
    assert rate0 == 0.5 and warp.rate0 == 0.5
    np.testing.assert_allclose(changes, [(2.0, 2.4, 1.0)], atol=1e-9)


def test_transition_weight_follows_eq10_and_fades_after_release() -> None:
    """Eq. 10: α = (t − t0) / (t1 − t0) over the rise (α = t / T with T = t1 − t0), 1 until
    the release, then a linear fade over ``blend_s``; 0 before t0."""
    w = TransitionWindow(0, "collision", t0=1.0, t1=1.5, release=3.0)
    blend = 0.2
    got = [w.alpha(t, blend) for t in (0.9, 1.0, 1.125, 1.25, 1.5, 2.0, 3.0, 3.05, 3.2, 3.5)]
    np.testing.assert_allclose(got, [0.0, 0.0, 0.25, 0.5, 1.0, 1.0, 1.0, 0.75, 0.0, 0.0])

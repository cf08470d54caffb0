"""Mechanics of the contact-anticipating controller (seed A §3.3-3.5): re-timing to the
approach velocity at p_c, the Eq. 10 blend, release on contact. Its H4 results are not
validated yet (issue #5)."""

from __future__ import annotations

import numpy as np
import pytest

from ccm.control.anticipation import AnticipatoryAVIC
from ccm.errors import ConfigError

CONTACT = [{"name": "mid", "position": [0.0, 0.08], "kind": "collision"}]  # on the approach


def make(**anticipation) -> AnticipatoryAVIC:
    settings = {"init_noise_std": 1e-9, "init_std": 0.01, "sigma_scale": 2.0, **anticipation}
    c = AnticipatoryAVIC(anticipation=settings, k_free=300.0, k_max=3000.0)
    c.reset(2, 0.001)
    return c


@pytest.fixture
def pattern(composer):
    from ccm.tasks.task import load_task

    return load_task(composer(["task=slide_surfaces_2d"]).task, 0.001).pattern


def test_speed_reaches_the_approach_velocity_at_p_c(pattern) -> None:
    c = make()
    retimed = c.prepare(pattern, CONTACT, np.random.default_rng(0))
    (w,) = c._windows  # noqa: SLF001 - the one anticipated collision
    t_c = w.t1  # wall time at which the path reaches p_c
    s = retimed.sample(t_c)
    # inside C the target never moves faster than v_a (v_safe, 0.05 m/s), and reaches it
    speeds = [np.linalg.norm(retimed.sample(t).velocity) for t in np.linspace(t_c, w.release, 500)]
    assert max(speeds) <= 0.05 + 1e-9
    assert max(speeds) == pytest.approx(0.05, rel=0.01)
    assert retimed.warp.rate(t_c) == pytest.approx(retimed.warp.rate(w.release - 1e-6))
    belief = c.contact_map.contacts[0].belief
    assert belief.region_contains(s.position, 2.0)  # p_c is on the region's boundary
    assert not belief.region_contains(retimed.sample(t_c - 0.01).position, 2.0)
    assert retimed.duration > pattern.duration  # slower through C
    assert w.alpha(w.t0, c.blend_s) == 0.0 and w.alpha(t_c, c.blend_s) == 1.0  # Eq. 10 ramp


def test_contact_made_releases_the_transition_and_the_speed(pattern) -> None:
    c = make()
    retimed = c.prepare(pattern, CONTACT, np.random.default_rng(0))
    (w,) = c._windows  # noqa: SLF001
    t_hit = w.t1 + 0.05
    phi_before = retimed.warp.phi(t_hit)
    c._release(0, t_hit)  # noqa: SLF001 - as a detected collision at the expected contact
    assert retimed.warp.phi(t_hit) == pytest.approx(phi_before, abs=1e-12)  # φ continuous
    assert retimed.warp.rate(t_hit + c.blend_s + 1e-6) == pytest.approx(1.0)  # plan speed
    assert w.alpha(t_hit + c.blend_s, c.blend_s) == pytest.approx(0.0, abs=1e-12)  # base again


def test_bad_settings_name_the_key() -> None:
    with pytest.raises(ConfigError, match="controller.anticipation.bogus"):
        AnticipatoryAVIC(anticipation={"bogus": 1})
    with pytest.raises(ConfigError, match="controller.anticipation.use_kinds"):
        AnticipatoryAVIC(anticipation={"use_kinds": ["vision"]})

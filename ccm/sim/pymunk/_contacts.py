"""The contact wrench on the end-effector of :mod:`ccm.sim.pymunk.backend`, read from Chipmunk's
arbiters after each physics step (how it is measured: that module's docstring)."""

from __future__ import annotations

import pymunk


class ContactReader:
    """Sums the arbiters of the end-effector ``body`` after each physics step.

    Args:
        dt: physics step [s].
        rotates: whether the EE may rotate (exact per-point torque) or not (uniform
            pressure over the touching face).
    """

    def __init__(self, dt: float, rotates: bool) -> None:
        self._inv_dt = 1.0 / dt
        self._rotates = rotates
        self._body: pymunk.Body | None = None
        # scratch for _visit: fx, fy, torque, n points, friction, largest |impulse|
        self._acc: list[float] = [0.0, 0.0, 0.0, 0.0, -1.0, -1.0]

    def read(self, body: pymunk.Body) -> tuple[float, float, float, int, float]:
        """Contact force, torque about the EE centre, point count and touched friction."""
        self._body = body
        self._acc = [0.0, 0.0, 0.0, 0.0, -1.0, -1.0]
        body.each_arbiter(self._visit)
        fx, fy, tq, n, mu, _ = self._acc
        return fx, fy, tq, int(n), mu

    def _visit(self, arb: pymunk.Arbiter) -> None:
        """Accumulate one arbiter (called by ``Body.each_arbiter`` with the EE as shape 0)."""
        acc = self._acc
        inv_dt = self._inv_dt
        imp = arb.total_impulse  # impulse applied to the EE during the last step
        fx, fy = imp.x * inv_dt, imp.y * inv_dt
        pts = arb.contact_point_set.points
        body = self._body
        assert body is not None
        px, py = body.position
        tq = per_contact_torque(arb, inv_dt) if self._rotates else None
        if tq is None and pts:
            # Rotation locked: the solver's split of the impulse between the points of a flat
            # face is arbitrary, so take a uniform pressure (force at the points' centroid).
            cx = sum(p.point_a.x + p.point_b.x for p in pts) / (2 * len(pts))
            cy = sum(p.point_a.y + p.point_b.y for p in pts) / (2 * len(pts))
            tq = (cx - px) * fy - (cy - py) * fx
        acc[0] += fx
        acc[1] += fy
        acc[2] += tq or 0.0
        acc[3] += len(pts)
        if abs(imp.x) + abs(imp.y) > acc[5]:
            acc[5] = abs(imp.x) + abs(imp.y)
            acc[4] = float(arb.friction)  # = surface friction x EE friction 1.0


def per_contact_torque(arb: pymunk.Arbiter, inv_dt: float) -> float | None:
    """Exact contact torque from Chipmunk's per-point impulses, or None if unavailable.

    pymunk 7 has no public per-point impulse, so this reads the cffi ``cpArbiter`` struct
    (``contacts[i].jnAcc/jtAcc``, arms ``r1``/``r2``). During ``each_arbiter`` the flag
    ``swapped`` is set when the EE is Chipmunk's ``body_b``, which receives ``+j``.
    """
    try:
        a = arb._arbiter  # noqa: SLF001 - see docstring
        nx, ny, ee_is_b = a.n.x, a.n.y, bool(a.swapped)
        tq = 0.0
        for i in range(a.count):
            c = a.contacts[i]
            jx = nx * c.jnAcc - ny * c.jtAcc
            jy = ny * c.jnAcc + nx * c.jtAcc
            r = c.r2 if ee_is_b else c.r1
            tq += r.x * jy - r.y * jx
    except (AttributeError, TypeError):  # pragma: no cover - pymunk internals changed
        return None
    return (tq if ee_is_b else -tq) * inv_dt

"""Direct Chipmunk calls for the per-physics-step reads and writes of :mod:`ccm.sim.pymunk.backend`.

pymunk's properties wrap each Chipmunk call in Python (a ``Vec2d`` per read, an ``assert``
per write) and ``Space.step`` does bookkeeping for shapes added or removed during a step,
post-step callbacks and a first-step mass check. The end-effector's world adds nothing during
a step and registers no callbacks, so per step this module calls ``cpBodySetForce``,
``cpSpaceStep`` and ``cpBodyGetPosition``/``cpBodyGetVelocity`` itself: the same Chipmunk
functions with the same arguments (identical physics), ~2.5 µs less per physics step.
Whenever the space has pending bookkeeping it falls back to ``Space.step``; if pymunk's
internals are not as expected it uses the public API throughout.
"""

from __future__ import annotations

from typing import Any

import pymunk


class RawBody:
    """Per-step access to one dynamic ``body`` in ``space`` (see the module docstring)."""

    def __init__(self, space: pymunk.Space, body: pymunk.Body) -> None:
        self._space = space
        self._body = body
        try:
            from pymunk._chipmunk import lib  # noqa: PLC0415 - private, optional fast path

            self._lib: Any = lib
            self._cp_space = space._space  # noqa: SLF001 - see module docstring
            self._cp_body = body._body  # noqa: SLF001
            self._pending = (
                space._bodies_to_check,  # noqa: SLF001
                space._add_later,  # noqa: SLF001
                space._remove_later,  # noqa: SLF001
                space._post_step_callbacks,  # noqa: SLF001
            )
        except (ImportError, AttributeError):  # pragma: no cover - pymunk internals changed
            self._lib = None

    def set_force(self, fx: float, fy: float) -> None:
        """``body.force = (fx, fy)`` (cleared by Chipmunk after each step)."""
        if self._lib is None:  # pragma: no cover - public-API fallback
            self._body.force = (fx, fy)
        else:
            self._lib.cpBodySetForce(self._cp_body, (fx, fy))

    def step(self, dt: float) -> None:
        """``space.step(dt)``; Chipmunk's step directly when no bookkeeping is pending."""
        if self._lib is None or self._space.threaded or any(self._pending):
            self._space.step(dt)
        else:
            self._lib.cpSpaceStep(self._cp_space, dt)

    def advance(self, fx: float, fy: float, dt: float) -> tuple[float, float, float, float]:
        """:meth:`set_force`, :meth:`step` and :meth:`state` in one call (the hot path)."""
        lib = self._lib
        if lib is None or self._space.threaded or any(self._pending):
            self.set_force(fx, fy)
            self.step(dt)
            return self.state()
        body = self._cp_body
        lib.cpBodySetForce(body, (fx, fy))
        lib.cpSpaceStep(self._cp_space, dt)
        p = lib.cpBodyGetPosition(body)
        v = lib.cpBodyGetVelocity(body)
        return p.x, p.y, v.x, v.y

    def state(self) -> tuple[float, float, float, float]:
        """``(x, y, vx, vy)``: the body's position [m] and velocity [m/s]."""
        if self._lib is None:  # pragma: no cover - public-API fallback
            (x, y), (vx, vy) = self._body.position, self._body.velocity
            return x, y, vx, vy
        p = self._lib.cpBodyGetPosition(self._cp_body)
        v = self._lib.cpBodyGetVelocity(self._cp_body)
        return p.x, p.y, v.x, v.y

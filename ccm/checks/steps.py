"""The step objects' promise (issue #40): a controller keeps no view of them.

The simulator, the pattern and the controller may hand out the same ``Observation``,
``TargetSample`` and ``Command`` every step, their arrays updated in place (read-only to the
receiver, valid until the next step), as MuJoCo's ``MjData`` is. A controller that keeps
history must copy what it keeps: a kept view would silently change under it.

:func:`check_keeps_no_views` tests that promise by experiment: the controller runs a closed
loop on fresh copies of every step's objects, then a second controller of the same factory
is fed the same steps through one set of objects overwritten in place. Its commands must be
the first's, bit for bit: a controller that kept a view of an earlier step computes from
the later step's numbers instead. Each controller samples its own prepared pattern (a
re-timing controller's pattern follows it), as the runner does.
"""

from __future__ import annotations

import copy
from collections.abc import Callable
from typing import Any

import numpy as np

from ccm.core.types import Command, Observation


class ContractError(AssertionError):
    """A broken promise of the step contract: one line naming it."""


def check_keeps_no_views(
    make_controller: Callable[[], Any],
    sim: Any,
    pattern: Any,
    contacts: Any = (),
    steps: int = 300,
    seed: int = 0,
) -> None:
    """Raise :class:`ContractError` if the commands of a controller from ``make_controller``
    depend on whether its step objects are fresh or reused (module docstring); ``sim`` and
    ``pattern`` give the ``steps`` observations and targets (closed loop, seeded)."""
    fresh = make_controller()
    obs, _ = sim.reset(seed=seed)
    dim, dt = int(obs.position.shape[0]), float(sim.control_dt)
    fresh.reset(dim, dt)
    planned = pattern
    pattern = fresh.prepare(planned, contacts, np.random.default_rng(seed))
    seen: list[tuple[Observation, Command]] = []
    for _ in range(steps):
        o = copy.deepcopy(obs)
        cmd = fresh.step(o, copy.deepcopy(pattern.sample(obs.t)))
        seen.append((copy.deepcopy(o), _copied(cmd)))
        obs, _ = sim.step(cmd)
    reused = make_controller()
    reused.reset(dim, dt)
    # the controller's own (re-timed) pattern, sampled as the runner samples it
    pattern = reused.prepare(planned, contacts, np.random.default_rng(seed))
    o, t = copy.deepcopy(seen[0][0]), copy.deepcopy(pattern.sample(seen[0][0].t))
    for k, (o_k, want) in enumerate(seen):
        _overwrite(o, o_k)
        _overwrite(t, pattern.sample(o_k.t))
        got = reused.step(o, t)
        for part in ("force", "torque"):
            a, b = np.asarray(getattr(got, part)), getattr(want, part)
            if not np.array_equal(a, b, equal_nan=True):
                raise ContractError(
                    f"step {k}: the command's {part} differs when the step objects are reused "
                    f"({b.tolist()} on fresh objects, {a.tolist()} on reused ones): the "
                    "controller keeps a view of an earlier step's arrays; copy what you keep"
                )


def _copied(cmd: Command) -> Command:
    return Command(np.array(cmd.force, dtype=float), np.array(cmd.torque, dtype=float))


def _overwrite(dst: Any, src: Any) -> None:
    """Write ``src``'s values into ``dst``'s arrays in place (read-only afterwards); the
    scalar fields are assigned. An optional array that appears or disappears (a force
    direction) is replaced."""
    for name in dst.__slots__:
        new, old = getattr(src, name), getattr(dst, name)
        if isinstance(new, np.ndarray) and isinstance(old, np.ndarray) and new.shape == old.shape:
            old.flags.writeable = True
            old[...] = new
            old.flags.writeable = False
        else:
            setattr(dst, name, new.copy() if isinstance(new, np.ndarray) else new)

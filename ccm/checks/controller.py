"""The contract kit for controllers (issue #41), in the spirit of scikit-learn's
``check_estimator`` and Gymnasium's ``check_env``: the promises of
:class:`ccm.control.base.Controller`, each a named check run in a small world with a change
of contact (:mod:`ccm.checks.worlds`).

=============================  ==========================================================
check                          the promise
=============================  ==========================================================
``step_shapes``                ``reset(dim, dt)`` then ``step`` gives a ``Command`` with a
                               finite force of shape (dim,) and a torque shaped like the
                               observation's angular velocity, every step
``signals``                    ``signals()`` maps names to finite-or-NaN floats, with the
                               same keys every step
``deterministic``              two controllers from the factory, on the same seed, give the
                               same commands bit for bit
``finite_on_sensor_faults``    with the F/T sensor spiking (50 N) and dropping out, every
                               command stays finite
``keeps_no_views``             it copies what it keeps of the step objects
                               (:func:`ccm.checks.steps.check_keeps_no_views`)
``learned_state_round_trip``   ``state_dict()`` (if not None) is JSON, and a fresh
                               controller that loads it gives it back unchanged
=============================  ==========================================================

``factory`` is any zero-argument callable that returns a new controller. A failed check
raises :class:`ccm.checks.steps.ContractError` with one line: the check's name, the world,
and what broke.
"""

from __future__ import annotations

import json
from collections.abc import Callable, Iterator, Mapping
from typing import Any

import numpy as np

from ccm.checks.steps import ContractError, check_keeps_no_views
from ccm.checks.worlds import World, world
from ccm.core.errors import exception_line
from ccm.core.types import Command

Factory = Callable[[], Any]
#: the control steps each check runs: the whole world's pattern (0.4 s at 1 kHz)
STEPS = 400


def controller_checks(factory: Factory, where: World) -> Iterator[tuple[str, Callable[[], None]]]:
    """The named checks of the module docstring for controllers from ``factory`` in
    ``where``; each callable raises :class:`ContractError` if its promise is broken."""
    yield "step_shapes", lambda: _loop(factory, where)
    yield "signals", lambda: _check_signals(factory, where)
    yield "deterministic", lambda: _check_deterministic(factory, where)
    yield "finite_on_sensor_faults", lambda: _loop(factory, world(where.backend, faults=True))
    yield "keeps_no_views", lambda: _check_views(factory, where)
    yield "learned_state_round_trip", lambda: _check_state(factory, where)


def check_controller(factory: Factory, backends: tuple[str, ...] = ("pymunk2d",)) -> None:
    """Run every check on every backend in ``backends``; the first broken promise raises
    :class:`ContractError` naming its check and backend."""
    for backend in backends:
        for name, check in controller_checks(factory, world(backend)):
            run_check(name, backend, check)


def run_check(name: str, backend: str, check: Callable[[], None]) -> None:
    """Run one check; a broken promise (or any error) becomes one line naming it."""
    try:
        check()
    except ContractError as exc:
        raise ContractError(f"{name} ({backend}): {exc}") from exc
    except Exception as exc:  # noqa: BLE001 - a controller's own error breaks the check too
        raise ContractError(f"{name} ({backend}): {exception_line(exc)}") from exc


def parametrize_with_checks(factories: Mapping[str, Factory],
                            backends: tuple[str, ...] = ("pymunk2d",)) -> Any:  # fmt: skip
    """A ``pytest.mark.parametrize`` over (controller, backend, check), with ids such as
    ``my_ctrl-pymunk2d-deterministic``; the test takes one argument, ``check``, and calls
    it::

        @parametrize_with_checks({"my_ctrl": lambda: MyController(stiffness=300.0)})
        def test_my_controller(check):
            check()
    """
    import pytest  # the kit's pytest helper; ccm itself does not need pytest

    params = []
    for label, factory in factories.items():
        for backend in backends:
            for name in _CHECK_NAMES:
                params.append(pytest.param(_deferred(factory, backend, name),
                                           id=f"{label}-{backend}-{name}"))  # fmt: skip
    return pytest.mark.parametrize("check", params)


def _deferred(factory: Factory, backend: str, name: str) -> Callable[[], None]:
    """The check ``name`` for ``factory`` on ``backend``, its world built when called."""

    def check() -> None:
        checks = dict(controller_checks(factory, world(backend)))
        run_check(name, backend, checks[name])

    return check


#: the checks' names, in order (the checks are lazy: listing them runs nothing)
_CHECK_NAMES = tuple(name for name, _ in controller_checks(lambda: None, None))  # type: ignore[arg-type]


def _loop(factory: Factory, where: World, seed: int = 0,
          on_step: Callable[[int, Any], None] | None = None) -> list[Command]:  # fmt: skip
    """Close the loop over the world's pattern; check each command's type, shapes and
    finiteness; return copies of the commands."""
    ctrl, sim = factory(), where.make_sim()
    try:
        obs, _ = sim.reset(seed=seed)
        dim = where.task.dim
        ctrl.reset(dim, sim.control_dt)
        pattern = ctrl.prepare(where.task.pattern, where.task.contacts,
                               np.random.default_rng(seed))  # fmt: skip
        out = []
        for k in range(STEPS):
            cmd = ctrl.step(obs, pattern.sample(obs.t))
            _check_command(k, cmd, dim, obs.ang_vel.shape)
            out.append(Command(np.array(cmd.force, float), np.array(cmd.torque, float)))
            if on_step is not None:
                on_step(k, ctrl)
            obs, _ = sim.step(cmd)
        return out
    finally:
        sim.close()


def _check_command(k: int, cmd: Any, dim: int, torque_shape: tuple[int, ...]) -> None:
    if not isinstance(cmd, Command):
        raise ContractError(f"step {k}: step() returned {type(cmd).__name__}, not a Command")
    force, torque = np.asarray(cmd.force), np.asarray(cmd.torque)
    if force.shape != (dim,) or torque.shape != torque_shape:
        raise ContractError(
            f"step {k}: the command's force has shape {force.shape} and torque "
            f"{torque.shape}; the task needs {(dim,)} and {torque_shape}"
        )
    if not (np.all(np.isfinite(force)) and np.all(np.isfinite(torque))):
        raise ContractError(
            f"step {k}: non-finite command (force {force.tolist()}, torque {torque.tolist()})"
        )


def _check_signals(factory: Factory, where: World) -> None:
    keys: list[set[str]] = []

    def on_step(k: int, ctrl: Any) -> None:
        sig = ctrl.signals()
        if not isinstance(sig, Mapping):
            raise ContractError(f"step {k}: signals() returned {type(sig).__name__}, not a dict")
        for name, value in sig.items():
            if not isinstance(name, str) or not isinstance(value, int | float):
                raise ContractError(f"step {k}: signal {name!r} = {value!r} is not a float")
        if keys and set(sig) != keys[0]:
            changed = sorted(set(sig) ^ keys[0])
            raise ContractError(f"step {k}: signals() keys changed ({', '.join(changed)})")
        keys.append(set(sig))

    _loop(factory, where, on_step=on_step)


def _check_deterministic(factory: Factory, where: World) -> None:
    first, second = _loop(factory, where, seed=3), _loop(factory, where, seed=3)
    for k, (a, b) in enumerate(zip(first, second, strict=True)):
        if not (np.array_equal(a.force, b.force) and np.array_equal(a.torque, b.torque)):
            raise ContractError(
                f"step {k}: two controllers on the same seed commanded {a.force.tolist()} "
                f"and {b.force.tolist()}; draw randomness only from the generator that "
                "prepare() is given"
            )


def _check_views(factory: Factory, where: World) -> None:
    sim = where.make_sim()
    try:
        check_keeps_no_views(factory, sim, where.task.pattern, where.task.contacts, steps=STEPS)
    finally:
        sim.close()


def _check_state(factory: Factory, where: World) -> None:
    learned: list[Any] = []

    def keep(k: int, ctrl: Any) -> None:
        if k == STEPS - 1:
            ctrl.end_trial()
            learned.append(ctrl.state_dict())

    _loop(factory, where, on_step=keep)
    state = learned[0]
    if state is None:
        return  # learns nothing across trials
    try:
        text = json.dumps(state, allow_nan=False)
    except (TypeError, ValueError) as exc:
        raise ContractError(f"state_dict() is not plain JSON: {exc}") from None
    fresh = factory()
    fresh.reset(where.task.dim, where.control_dt)
    fresh.load_state_dict(json.loads(text))
    again = json.dumps(fresh.state_dict(), allow_nan=False)
    if again != text:
        at = next((i for i, (a, b) in enumerate(zip(text, again, strict=False)) if a != b),
                  min(len(text), len(again)))  # fmt: skip
        raise ContractError(
            f"load_state_dict(state_dict()) changes the state (first at character {at}: "
            f"{text[max(0, at - 30) : at + 30]!r} -> {again[max(0, at - 30) : at + 30]!r})"
        )


__all__ = [
    "ContractError", "check_controller", "controller_checks", "parametrize_with_checks",
    "run_check",
]  # fmt: skip

"""The contract kit for simulators (issue #41): the promises of :class:`ccm.sim.base.Simulator`
that a controller and the runner rely on, each a named check.

=============================  ==========================================================
check                          the promise
=============================  ==========================================================
``step_shapes``                ``reset(seed)`` and ``step(command)`` give an Observation
                               and a StepInfo shaped for the simulator's ``dim`` (positions
                               and forces (dim,); 1 or 3 rotational axes; a quaternion in
                               3-D), with ``t`` advancing by ``control_dt`` from 0
``deterministic``              the same seed and commands give the same observations, bit
                               for bit, sensor noise included
``extra_keys``                 ``StepInfo.extra`` has the same keys every step (the recorder
                               fixes its columns at the first)
``measures_external_wrench``   under a pushing command the measured force follows the true
                               external force (``StepInfo.true_force``), never the command
``refuses_non_finite``         a NaN command raises ``SimulationDiverged``
``closes``                     ``with`` closes it, and closing twice is harmless
=============================  ==========================================================

``make_sim`` is a zero-argument callable that returns a new simulator of the scene to check,
whose first ``STEPS`` control steps from the start pose are free of contact under the kit's
commands (a 5 N push along x). :func:`ccm.checks.worlds.world` gives such factories for the
built-in backends.
"""

from __future__ import annotations

from collections.abc import Callable, Iterator
from typing import Any

import numpy as np

from ccm.checks.controller import run_check
from ccm.checks.steps import ContractError
from ccm.core.errors import SimulationDiverged
from ccm.core.types import Command, Observation, StepInfo

SimFactory = Callable[[], Any]
#: control steps per check; the push [N] along x the checks command (chosen: moves a 1 kg
#: block by ~1 cm in 0.1 s, short of anything in the check worlds)
STEPS, PUSH_N = 60, 5.0


def simulator_checks(make_sim: SimFactory) -> Iterator[tuple[str, Callable[[], None]]]:
    """The named checks of the module docstring for simulators from ``make_sim``."""
    yield "step_shapes", lambda: _check_shapes(make_sim)
    yield "deterministic", lambda: _check_deterministic(make_sim)
    yield "extra_keys", lambda: _check_extra_keys(make_sim)
    yield "measures_external_wrench", lambda: _check_wrench(make_sim)
    yield "refuses_non_finite", lambda: _check_non_finite(make_sim)
    yield "closes", lambda: _check_closes(make_sim)


def check_simulator(make_sim: SimFactory, label: str = "simulator") -> None:
    """Run every check; the first broken promise raises :class:`ContractError` naming its
    check and ``label``."""
    for name, check in simulator_checks(make_sim):
        run_check(name, label, check)


def _push(sim: Any, obs: Observation) -> Command:
    force = np.zeros(obs.position.shape[0])
    force[0] = PUSH_N
    return Command(force, np.zeros(obs.ang_vel.shape[0]))


def _run(make_sim: SimFactory, seed: int = 0) -> list[tuple[Observation, StepInfo, Command]]:
    """Reset with ``seed`` and push for ``STEPS`` steps: deep copies of every step."""
    import copy

    sim = make_sim()
    try:
        obs, info = sim.reset(seed=seed)
        out = [(copy.deepcopy(obs), copy.deepcopy(info), None)]
        for _ in range(STEPS):
            cmd = _push(sim, obs)
            obs, info = sim.step(cmd)
            out.append((copy.deepcopy(obs), copy.deepcopy(info), cmd))
        return out  # type: ignore[return-value]
    finally:
        sim.close()


def _check_shapes(make_sim: SimFactory) -> None:
    sim = make_sim()
    dim, dt = sim.dim, float(sim.control_dt)
    sim.close()
    if dim not in (2, 3) or not dt > 0.0:
        raise ContractError(f"dim {dim!r} and control_dt {dt!r}: need 2 or 3 and a period > 0")
    r, q = (1, 1) if dim == 2 else (3, 4)
    for k, (obs, info, _) in enumerate(_run(make_sim)):
        if not isinstance(obs, Observation) or not isinstance(info, StepInfo):
            raise ContractError(f"step {k}: got {type(obs).__name__}, {type(info).__name__}; "
                                "need an Observation and a StepInfo")  # fmt: skip
        want = {"position": (dim,), "orientation": (q,), "lin_vel": (dim,), "ang_vel": (r,),
                "force": (dim,), "torque": (r,)}  # fmt: skip
        for name, shape in want.items():
            got = np.shape(getattr(obs, name))
            if got != shape:
                raise ContractError(f"step {k}: observation {name} has shape {got}, need {shape}")
        if np.shape(info.true_force) != (dim,) or np.shape(info.true_torque) != (r,):
            raise ContractError(f"step {k}: StepInfo's true force/torque shapes do not match")
        if not np.isclose(obs.t, k * dt, rtol=0.0, atol=1e-9):
            raise ContractError(f"step {k}: t = {obs.t!r}, need {k} × control_dt = {k * dt!r}")


def _check_deterministic(make_sim: SimFactory) -> None:
    first, second = _run(make_sim, seed=5), _run(make_sim, seed=5)
    for k, ((a, _, _), (b, _, _)) in enumerate(zip(first, second, strict=True)):
        for name in ("position", "lin_vel", "force", "torque"):
            if not np.array_equal(getattr(a, name), getattr(b, name)):
                raise ContractError(
                    f"step {k}: {name} differs between two runs on seed 5 "
                    f"({getattr(a, name).tolist()} vs {getattr(b, name).tolist()}); draw "
                    "randomness from generators seeded at reset(seed)"
                )


def _check_extra_keys(make_sim: SimFactory) -> None:
    steps = _run(make_sim)
    keys = set(steps[0][1].extra)
    for k, (_, info, _) in enumerate(steps):
        if set(info.extra) != keys:
            changed = ", ".join(sorted(set(info.extra) ^ keys))
            raise ContractError(f"step {k}: StepInfo.extra keys changed ({changed})")


def _check_wrench(make_sim: SimFactory) -> None:
    """The measured force is the external one (a modelled sensor: noise, bias and faults
    allowed, so compared over the run's mean), not the commanded push."""
    steps = _run(make_sim)[1:]
    if any(info.n_contacts for _, info, _ in steps):
        raise ContractError("the scene has contact within the first steps; the check needs "
                            "free space under a 5 N push from the start pose")  # fmt: skip
    meas = np.mean([obs.force for obs, _, _ in steps], axis=0)
    true = np.mean([info.true_force for _, info, _ in steps], axis=0)
    cmd = np.mean([c.force for _, _, c in steps], axis=0)
    tol = 0.1 * PUSH_N  # 0.5 N: sensor noise averages out over the steps, bias must be small
    if np.abs(meas - true).max() > tol:
        echo = " (it is the command)" if np.abs(meas - cmd).max() < tol else ""
        raise ContractError(f"the mean measured force {meas.round(3).tolist()} N is not the "
                            f"true external force {true.round(3).tolist()} N{echo}")  # fmt: skip


def _check_non_finite(make_sim: SimFactory) -> None:
    sim = make_sim()
    try:
        obs, _ = sim.reset(seed=0)
        bad = _push(sim, obs)
        bad.force[0] = np.nan
        try:
            sim.step(bad)
        except SimulationDiverged:
            return
        raise ContractError("a NaN command did not raise SimulationDiverged")
    finally:
        sim.close()


def _check_closes(make_sim: SimFactory) -> None:
    with make_sim() as sim:
        obs, _ = sim.reset(seed=0)
        sim.step(_push(sim, obs))
    sim.close()  # a second close is harmless

"""One trial's closed loop: sample the target P, control, record, step the simulator.

The loop touches only the :class:`ccm.sim.base.Simulator` and
:class:`ccm.control.base.Controller` contracts. The controller sees the Observation only;
the simulator's ground truth (``StepInfo``) goes to the recorder.
"""

from __future__ import annotations

import math
from collections.abc import Callable
from typing import Any

import numpy as np

from ccm.core.errors import (
    SimulationDiverged,
)
from ccm.core.records import TrialRecorder
from ccm.core.types import Observation, StepInfo
from ccm.experiment.components import Components
from ccm.sim.base import Simulator, check_state_finite


def run_trial(
    comp: Components,
    seed: int,
    duration_s: float,
    progress: Callable[[int], None] | None = None,
    *,
    max_extension_s: float = math.inf,
    on_step: Callable[[Simulator], None] | None = None,
    expect: Callable[[int], None] | None = None,
) -> TrialRecorder:
    """Run one trial: sample P, control, step the simulator, record. Raises on divergence.

    ``duration_s`` is the trial length for the planned pattern. A controller may re-time it
    (:meth:`Controller.prepare`), also during the trial: the trial then lasts
    ``duration_s`` plus however much longer the re-timed pattern currently is, up to
    ``max_extension_s`` (0 = never longer). The recorder's ``pattern_duration`` is the
    pattern's final duration (for the completion time). ``on_step(sim)``, if given, is called
    once per control step right after the step is recorded (before the simulator steps), e.g. to log
    the joint encoders an offline learner needs (:mod:`ccm.analyses.h3_data`). ``expect(n)``,
    if given, gets the trial's step count once the controller has re-timed the pattern (a
    progress bar's estimate).
    """
    obs, info = comp.sim.reset(seed=seed)
    comp.controller.reset(comp.task.dim, comp.sim.control_dt)
    planned = comp.task.pattern
    pattern = comp.controller.prepare(planned, comp.task.contacts, np.random.default_rng(seed))
    dt = comp.sim.control_dt

    memo = [math.nan, 0]  # (pattern duration, steps): recomputed only when P is re-timed

    def n_steps() -> int:
        if pattern.duration != memo[0]:
            extra = min(max(pattern.duration - planned.duration, 0.0), max_extension_s)
            memo[:] = [pattern.duration, max(1, int(math.floor((duration_s + extra) / dt + 1e-9)))]
        return int(memo[1])

    if expect is not None:
        expect(n_steps())

    # no gc.disable() (issue #20 had one): the recorder keeps no per-step Python object, so
    # the collector has nothing growing to rescan (issue #40; measured on multi_spring, fixed
    # impedance and AVIC: the same time with the collector on)
    rec = _closed_loop(comp, pattern, obs, info, n_steps, progress, on_step)
    rec.arrays()
    rec.pattern_duration = float(pattern.duration)
    return rec


def _closed_loop(
    comp: Components,
    pattern: Any,
    obs: Observation,
    info: StepInfo,
    n_steps: Callable[[], int],
    progress: Callable[[int], None] | None,
    on_step: Callable[[Simulator], None] | None = None,
) -> TrialRecorder:
    """The per-step loop of :func:`run_trial`; ``n_steps()`` is re-read every step (a
    re-timing controller may change the pattern's duration during the trial)."""
    sim, ctrl = comp.sim, comp.controller
    max_speed = float(getattr(sim, "max_speed", math.inf))
    tick = max(1, n_steps() // 100)
    rec = TrialRecorder(comp.task.dim, list(ctrl.signals()), sorted(info.extra))
    k = -1
    while (k := k + 1) < n_steps():
        target = pattern.sample(obs.t)
        cmd = ctrl.step(obs, target)
        rec.record(obs, target, cmd, info, ctrl.signals())
        if on_step is not None:
            on_step(sim)
        obs, info = sim.step(cmd)
        reason = check_state_finite(obs, max_speed)
        if reason is not None:
            raise SimulationDiverged(reason)
        if progress is not None and (k + 1) % tick == 0:
            progress(tick)
    return rec

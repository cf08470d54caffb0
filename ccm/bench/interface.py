"""What ccm's per-step interface costs by itself: the ceiling of a loop row (issue #20).

Every control step of ccm's loop (:func:`ccm.experiment.trial.run_trial`) passes objects
across its parts: the pattern gives a :class:`~ccm.core.types.TargetSample`, the controller a
:class:`~ccm.core.types.Command`, the simulator an :class:`~ccm.core.types.Observation` and a
:class:`~ccm.core.types.StepInfo` (with its truth extras), and the
:class:`~ccm.core.records.TrialRecorder` copies the numbers of all four and the controller's
signals, then assembles the columns. Each object still carries fresh arrays: the step types
are made anew each step (issue #40 reuses them; the recorder already copies what it logs).

:func:`interface_cost` builds and records exactly those objects for a row, with the row's
dimensions, truth-extra keys and signal keys, and no arithmetic, sampling or physics. The
time it takes is a lower bound on ccm's own cost per control step. Any controller behind
this interface, however it is compiled, cannot do better. Added to the raw engine loop
(:mod:`ccm.bench.engines`), it gives the row's **ceiling**: the × real time that ccm's loop
would reach if the control law, the target sampling, the simulator wrapper and the sensor
cost nothing.
"""

from __future__ import annotations

import statistics
import time
from typing import Any

import numpy as np

from ccm.core.records import TrialRecorder
from ccm.core.types import Command, Observation, StepInfo, TargetSample


def interface_cost(
    sim: Any, controller: Any, steps: int, repeats: int = 3, record: bool = True
) -> float:
    """Median wall seconds of ``steps`` control steps of the interface alone (module
    docstring) for ``sim`` and ``controller``; with ``record=False`` the objects only, not
    kept or assembled (the part a recorder of preallocated arrays would not remove).
    ``sim.reset(seed=0)`` supplies the dimensions and the truth-extra keys."""
    obs, info = sim.reset(seed=0)
    shapes = (obs.position.shape[0], obs.orientation.shape[0], obs.torque.shape[0])
    extra_keys = sorted(info.extra)
    signals = {k: 0.0 for k in controller.signals()}
    walls = [_interface_pass(shapes, extra_keys, signals, steps, record) for _ in range(repeats)]
    return statistics.median(walls)


def _interface_pass(
    shapes: tuple[int, int, int],
    extra_keys: list[str],
    signals: dict[str, float],
    steps: int,
    record: bool,
) -> float:
    """One timed pass: build ``steps`` steps of objects, and record and assemble them."""
    n, n_orn, n_rot = shapes
    vec, orn, rot = (0.0,) * n, (0.0,) * n_orn, (0.0,) * n_rot
    extra_values = (0.0,) * len(extra_keys)
    rec = TrialRecorder(n, list(signals), extra_keys)
    arr = np.array
    t0 = time.perf_counter()
    for k in range(steps):
        t = 1e-3 * k
        target = TargetSample(t, arr(vec), arr(vec), arr(vec), arr(orn))
        cmd = Command(arr(vec), arr(rot))
        obs = Observation(t, arr(vec), arr(orn), arr(vec), arr(rot), arr(vec), arr(rot))
        info = StepInfo(
            arr(vec), arr(rot), arr(vec), 0, dict(zip(extra_keys, extra_values, strict=True))
        )
        sig = dict(signals)
        if record:
            rec.record(obs, target, cmd, info, sig)
    if record:
        rec.arrays()
    return time.perf_counter() - t0

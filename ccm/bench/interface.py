"""What ccm's per-step interface costs by itself: the ceiling of a loop row (issue #20).

Every control step of ccm's loop (:func:`ccm.experiment.trial.run_trial`) passes objects
across its parts: the pattern gives a :class:`~ccm.core.types.TargetSample`, the controller a
:class:`~ccm.core.types.Command`, the simulator an :class:`~ccm.core.types.Observation` and a
:class:`~ccm.core.types.StepInfo` (with its truth extras), and the
:class:`~ccm.core.records.TrialRecorder` copies the numbers of all four and the controller's
signals, then assembles the columns. Since issue #40 the simulator and the pattern hand out
one object each per trial, updated in place (their arrays read-only views of one buffer);
the controller still makes a new Command every step.

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
from ccm.core.vector import readonly


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
    """One timed pass: update ``steps`` steps of objects in place as the simulator and the
    pattern do (one buffer write each, the scalar fields, the truth extras), make a Command
    as a controller does, and record and assemble them."""
    n, n_orn, n_rot = shapes
    tgt_buf, obs_buf = np.zeros((3, n)), np.zeros(3 * n + n_orn + 2 * n_rot)
    tgt_rows = np.zeros((3, n))  # what a segment's evaluation gives
    obs_row = (0.0,) * obs_buf.shape[0]  # the simulator's state as floats
    o = np.cumsum([0, n, n_orn, n, n_rot, n, n_rot])
    obs = Observation(0.0, *(readonly(obs_buf[o[i] : o[i + 1]]) for i in range(6)))
    target = TargetSample(0.0, *(readonly(tgt_buf[i]) for i in range(3)), np.zeros(n_orn))
    info = StepInfo(obs.force, obs.torque, obs.force, 0, dict.fromkeys(extra_keys, 0.0))
    extra, vec, rot = info.extra, (0.0,) * n, (0.0,) * n_rot
    rec = TrialRecorder(n, list(signals), extra_keys)
    arr = np.array
    t0 = time.perf_counter()
    for k in range(steps):
        t = 1e-3 * k
        tgt_buf[...] = tgt_rows
        target.t, target.force_dir, target.force_mag, target.segment = t, None, 0.0, 0
        cmd = Command(arr(vec), arr(rot))
        obs_buf[:] = obs_row
        obs.t, info.n_contacts = t, 0
        for key in extra_keys:
            extra[key] = 0.0
        sig = dict(signals)
        if record:
            rec.record(obs, target, cmd, info, sig)
    if record:
        rec.arrays()
    return time.perf_counter() - t0

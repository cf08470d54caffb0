"""Trial time series and atomic file writes for the run directory (DESIGN.md, run directory)."""

from __future__ import annotations

import json
import os
import tempfile
from collections.abc import Mapping, Sequence
from pathlib import Path
from typing import Any

import numpy as np

from ccm.types import Command, Observation, StepInfo, TargetSample

AXES = "xyz"
ROT_AXES_2D = ("z",)
ROT_AXES_3D = ("x", "y", "z")


def write_atomic(path: Path, text: str) -> None:
    """Write ``text`` to ``path`` through a temporary file and a rename (never half-written)."""
    path.parent.mkdir(parents=True, exist_ok=True)
    fd, tmp = tempfile.mkstemp(dir=path.parent, prefix=f".{path.name}.", suffix=".tmp")
    try:
        with os.fdopen(fd, "w", encoding="utf-8") as fh:
            fh.write(text)
        os.replace(tmp, path)
    except BaseException:
        Path(tmp).unlink(missing_ok=True)
        raise


def write_json_atomic(path: Path, data: Any) -> None:
    """Atomically write ``data`` as pretty JSON (keys in insertion order, strict: no NaN)."""
    write_atomic(path, json.dumps(data, indent=2, allow_nan=False) + "\n")


class TrialRecorder:
    """Preallocated per-step log of one trial: target, state, wrench, command, signals, truth.

    Columns (units in the docs of :mod:`ccm.types`): ``t``, ``segment``, ``target_pos_*``,
    ``target_vel_*``, ``pos_*``, ``vel_*``, ``force_*`` (measured), ``torque_*`` (measured),
    ``true_force_*``, ``contact_force_*``, ``cmd_force_*``, ``cmd_torque_*``, ``force_dir_*``,
    ``force_target_N``, ``n_contacts``, the controller's signals and ``truth_*`` extras.
    """

    def __init__(
        self,
        capacity: int,
        dim: int,
        signal_keys: Sequence[str],
        extra_keys: Sequence[str],
    ) -> None:
        ax = AXES[:dim]
        rot = ROT_AXES_2D if dim == 2 else ROT_AXES_3D
        self.dim = dim
        self.signal_keys = list(signal_keys)
        self.extra_keys = list(extra_keys)
        self.columns: list[str] = ["t", "segment"]
        for prefix in ("target_pos", "target_vel", "pos", "vel", "force"):
            self.columns += [f"{prefix}_{a}" for a in ax]
        self.columns += [f"torque_{a}" for a in rot]
        for prefix in ("true_force", "contact_force", "cmd_force"):
            self.columns += [f"{prefix}_{a}" for a in ax]
        self.columns += [f"cmd_torque_{a}" for a in rot]
        self.columns += [f"force_dir_{a}" for a in ax]
        self.columns += ["force_target_N", "n_contacts"]
        self.columns += self.signal_keys
        self.columns += [f"truth_{k}" for k in self.extra_keys]
        self._data = np.full((capacity, len(self.columns)), np.nan)
        self._n = 0
        self._zeros = np.zeros(dim)

    def record(
        self,
        obs: Observation,
        target: TargetSample,
        cmd: Command,
        info: StepInfo,
        signals: Mapping[str, float],
    ) -> None:
        """Append one control step (the state ``obs`` at which ``cmd`` was computed)."""
        fdir = target.force_dir if target.force_dir is not None else self._zeros
        row = np.concatenate(
            (
                (obs.t, target.segment),
                target.position,
                target.velocity,
                obs.position,
                obs.lin_vel,
                obs.force,
                obs.torque,
                info.true_force,
                info.contact_force,
                cmd.force,
                cmd.torque,
                fdir,
                (target.force_mag if target.force_dir is not None else 0.0, info.n_contacts),
                [signals.get(k, np.nan) for k in self.signal_keys],
                [info.extra.get(k, np.nan) for k in self.extra_keys],
            )
        )
        self._data[self._n] = row
        self._n += 1

    def __len__(self) -> int:
        return self._n

    def arrays(self) -> dict[str, np.ndarray]:
        """The recorded columns as a dict of 1-D arrays (views)."""
        data = self._data[: self._n]
        return {name: data[:, i] for i, name in enumerate(self.columns)}

    def write_csv(self, path: Path) -> None:
        """Write the log as CSV with a header row (atomic)."""
        import io

        buf = io.StringIO()
        np.savetxt(
            buf,
            self._data[: self._n],
            delimiter=",",
            header=",".join(self.columns),
            comments="",
            fmt="%.9g",
        )
        write_atomic(path, buf.getvalue())


def read_csv(path: Path) -> dict[str, np.ndarray]:
    """Read a time series written by :meth:`TrialRecorder.write_csv`."""
    with open(path, encoding="utf-8") as fh:
        header = fh.readline().strip().split(",")
    data = np.loadtxt(path, delimiter=",", skiprows=1, ndmin=2)
    return {name: data[:, i] for i, name in enumerate(header)}

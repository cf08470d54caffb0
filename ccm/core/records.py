"""Trial time series (in memory) and atomic file writes for the run directory (layout: README;
on disk: :mod:`ccm.core.timeseries`)."""

from __future__ import annotations

import json
import operator
import os
import tempfile
from collections.abc import Iterator, Mapping, Sequence
from contextlib import contextmanager
from pathlib import Path
from typing import Any

import numpy as np

from ccm.core.types import Command, Observation, StepInfo, TargetSample

AXES = "xyz"
ROT_AXES_2D = ("z",)
ROT_AXES_3D = ("x", "y", "z")


@contextmanager
def atomic_path(path: Path) -> Iterator[Path]:
    """A temporary path beside ``path``, renamed onto it when the block ends without error
    (removed otherwise): readers never see a half-written file."""
    path.parent.mkdir(parents=True, exist_ok=True)
    fd, tmp = tempfile.mkstemp(dir=path.parent, prefix=f".{path.name}.", suffix=".tmp")
    os.close(fd)
    try:
        yield Path(tmp)
        os.chmod(tmp, 0o666 & ~_umask())  # mkstemp creates 0600; give the usual file mode
        os.replace(tmp, path)
    except BaseException:
        Path(tmp).unlink(missing_ok=True)
        raise


def write_atomic(path: Path, text: str) -> None:
    """Write ``text`` to ``path`` through a temporary file and a rename (never half-written)."""
    with atomic_path(path) as tmp:
        tmp.write_text(text, encoding="utf-8")


def save_figure(fig: Any, path: Path, dpi: int = 110) -> None:
    """Lay out ``fig``, write it to ``path`` as PNG atomically, and close it.

    The figure is drawn once at ``dpi`` and its pixels are encoded once, by Pillow (the same
    file as ``savefig`` followed by a re-encode, without the first PNG encode and decode:
    ~40 % of a figure's cost, issue #20). An opaque figure (every pixel's alpha 255, as with
    matplotlib's default white face) is stored as RGB rather than RGBA: the same pixels in
    ~12 % fewer bytes."""
    import matplotlib.pyplot as plt
    from PIL import Image

    try:
        fig.tight_layout()
        fig.set_dpi(dpi)
        fig.canvas.draw()
        rgba = np.asarray(fig.canvas.buffer_rgba())
        opaque = bool(np.all(rgba[..., 3] == 255))
        image = Image.fromarray(np.ascontiguousarray(rgba[..., :3]) if opaque else rgba)
        with atomic_path(path) as tmp:
            image.save(tmp, format="png")
    finally:
        plt.close(fig)


def _umask() -> int:
    """The process umask (read by setting and restoring it; there is no getter)."""
    mask = os.umask(0o022)
    os.umask(mask)
    return mask


def read_json_object(path: Path) -> dict[str, Any] | None:
    """The JSON object (dict) stored in ``path``; None if the file is missing or unreadable, is
    not UTF-8 JSON, or holds another JSON value: a record that cannot be used."""
    try:
        data = json.loads(Path(path).read_text(encoding="utf-8"))
    except (OSError, ValueError):  # ValueError: bad JSON, or bytes that are not UTF-8
        return None
    return data if isinstance(data, dict) else None


def write_json_atomic(path: Path, data: Any, compact: bool = False) -> None:
    """Atomically write ``data`` as JSON (keys in insertion order, strict: no NaN): indented,
    or ``compact`` (no whitespace: learned states are mostly long number arrays, and
    indentation puts each number on its own line, nearly doubling the file)."""
    if compact:
        text = json.dumps(data, separators=(",", ":"), allow_nan=False)
    else:
        text = json.dumps(data, indent=2, allow_nan=False)
    write_atomic(path, text + "\n")


def axes_columns(log: Mapping[str, np.ndarray], prefix: str, dim: int) -> np.ndarray:
    """The columns ``<prefix>_x, <prefix>_y[, <prefix>_z]`` of a trial's log as a (T, dim)
    array (the column names :class:`TrialRecorder` writes)."""
    return np.column_stack([log[f"{prefix}_{a}"] for a in AXES[:dim]])


_F64 = np.dtype(np.float64)
_DTYPE = operator.attrgetter("dtype")


def _flat(values: Sequence[np.ndarray]) -> np.ndarray:
    """The per-step vectors end to end, as one float array. Contiguous float64 vectors (what
    every backend and pattern gives) are joined as bytes, ~5x cheaper per vector than
    ``np.concatenate``, whose per-array overhead dominates for 1-7 entries; anything else
    goes through ``np.concatenate``. The same numbers either way."""
    if set(map(_DTYPE, values)) == {_F64}:
        try:
            return np.frombuffer(bytearray(b"".join(values)), dtype=_F64)
        except (BufferError, TypeError):  # a strided view has no simple buffer
            pass
    return np.concatenate(values).astype(float, copy=False)


def _columns(keys: Sequence[str], dicts: Sequence[Mapping[str, float]]) -> dict[str, np.ndarray]:
    """Column ``k`` of a list of per-step dicts for each of ``keys`` (NaN where a step lacks
    ``k``): one table through ``itemgetter`` when every step has every key, as a
    controller's signals and a simulator's truth extras do."""
    if not keys:
        return {}
    try:
        table = np.array(list(map(operator.itemgetter(*keys), dicts)), dtype=float)
    except KeyError:
        return {k: np.array([d.get(k, np.nan) for d in dicts], dtype=float) for k in keys}
    table = table.reshape(len(dicts), len(keys))  # one key: itemgetter gives scalars
    return {k: table[:, i] for i, k in enumerate(keys)}


class TrialRecorder:
    """Per-step log of one trial: target, state, wrench, command, signals, truth.

    ``record`` only keeps references (it runs every control step, so it must be cheap); the
    table is assembled column-wise when first read. Columns (units in :mod:`ccm.core.types`):
    ``t``, ``segment``, ``target_pos_*``, ``target_vel_*``, ``pos_*``, ``vel_*``, ``force_*``
    (measured), ``torque_*`` (measured), ``true_force_*``, ``contact_force_*``,
    ``cmd_force_*``, ``cmd_torque_*``, ``force_dir_*``, ``force_target_N``, ``n_contacts``,
    the controller's signals and ``truth_*`` extras.
    """

    def __init__(self, dim: int, signal_keys: Sequence[str], extra_keys: Sequence[str]) -> None:
        self.dim = dim
        self.pattern_duration: float | None = None  # set by the runner: the (re-timed) P's end
        self.signal_keys = list(signal_keys)
        self.extra_keys = list(extra_keys)
        self._rows: list[tuple[Observation, TargetSample, Command, StepInfo, Mapping]] = []
        self._table: dict[str, np.ndarray] | None = None

    def record(
        self,
        obs: Observation,
        target: TargetSample,
        cmd: Command,
        info: StepInfo,
        signals: Mapping[str, float],
    ) -> None:
        """Append one control step (the state ``obs`` at which ``cmd`` was computed)."""
        self._rows.append((obs, target, cmd, info, signals))
        self._table = None

    def __len__(self) -> int:
        return len(self._rows)

    def arrays(self) -> dict[str, np.ndarray]:
        """The recorded columns as a dict of 1-D arrays, in column order."""
        if self._table is None:
            self._table = self._assemble()
        return self._table

    def _assemble(self) -> dict[str, np.ndarray]:
        rows = self._rows
        ax = AXES[: self.dim]
        rot = ROT_AXES_2D if self.dim == 2 else ROT_AXES_3D
        zeros = np.zeros(self.dim)
        out: dict[str, np.ndarray] = {
            "t": np.array([r[0].t for r in rows], dtype=float),
            "segment": np.array([r[1].segment for r in rows], dtype=float),
        }

        def put(prefix: str, names: Sequence[str], values: list[np.ndarray]) -> None:
            flat = _flat(values) if values else np.zeros(0)
            block = flat.reshape(len(rows), len(names))
            for i, name in enumerate(names):
                out[f"{prefix}_{name}"] = block[:, i]

        put("target_pos", ax, [r[1].position for r in rows])
        put("target_vel", ax, [r[1].velocity for r in rows])
        put("pos", ax, [r[0].position for r in rows])
        put("vel", ax, [r[0].lin_vel for r in rows])
        put("force", ax, [r[0].force for r in rows])
        put("torque", rot, [r[0].torque for r in rows])
        put("true_force", ax, [r[3].true_force for r in rows])
        put("contact_force", ax, [r[3].contact_force for r in rows])
        put("cmd_force", ax, [r[2].force for r in rows])
        put("cmd_torque", rot, [r[2].torque for r in rows])
        put("force_dir", ax, [zeros if r[1].force_dir is None else r[1].force_dir for r in rows])
        out["force_target_N"] = np.array(
            [0.0 if r[1].force_dir is None else r[1].force_mag for r in rows], dtype=float
        )
        out["n_contacts"] = np.array([r[3].n_contacts for r in rows], dtype=float)
        out.update(_columns(self.signal_keys, [r[4] for r in rows]))
        extras = _columns(self.extra_keys, [r[3].extra for r in rows])
        out.update((f"truth_{k}", v) for k, v in extras.items())
        return out

    @property
    def columns(self) -> list[str]:
        """Column names in file order."""
        return list(self.arrays())

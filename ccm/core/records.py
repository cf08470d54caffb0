"""Trial time series (in memory) and atomic file writes for the run directory (layout:
docs/user-guide/running.md, "What a run writes"; on disk: :mod:`ccm.core.timeseries`)."""

from __future__ import annotations

import json
import operator
import os
import tempfile
from array import array
from collections.abc import Callable, Iterator, Mapping, Sequence
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
_ONLY_F64 = {_F64}

#: the per-step vectors of a row, in column order, and whether their axes are rotational
_VECTORS = (
    ("target_pos", False), ("target_vel", False), ("pos", False), ("vel", False),
    ("force", False), ("torque", True), ("true_force", False), ("contact_force", False),
    ("cmd_force", False), ("cmd_torque", True), ("force_dir", False),
)  # fmt: skip


def _values(keys: Sequence[str]) -> Callable[[Mapping[str, float]], tuple]:
    """A function of a per-step mapping: its values at ``keys`` as a tuple (NaN where a step
    lacks a key), as a controller's signals and a simulator's truth extras give them."""
    if not keys:
        return lambda _d: ()
    get = operator.itemgetter(*keys)
    one = len(keys) == 1

    def values(d: Mapping[str, float]) -> tuple:
        try:
            v = get(d)
        except KeyError:
            return tuple(d.get(k, np.nan) for k in keys)
        return (v,) if one else v

    return values


def _extend(out: array, values: tuple) -> None:
    """Append a step's values to ``out`` as float64 (None as NaN, as numpy converts it)."""
    n = len(out)
    try:
        out.extend(values)
    except TypeError:  # None, or a type array() does not take: numpy's float conversion
        del out[n:]  # extend() appends one by one: undo a partial row
        out.extend(np.array(values, dtype=float).tolist())


def _table(keys: Sequence[str], values: array, n: int) -> dict[str, np.ndarray]:
    """Column ``k`` of the per-step values (row after row) for each of ``keys``."""
    if not keys:
        return {}
    table = np.frombuffer(values, dtype=_F64).reshape(n, len(keys)).copy()
    return {k: table[:, i] for i, k in enumerate(keys)}


class TrialRecorder:
    """Per-step log of one trial: target, state, wrench, command, signals, truth.

    ``record`` copies the step's numbers, so a simulator or a controller may update its
    arrays in place: what is logged is what they held at that step. The table is built once,
    when first read. Columns (units in :mod:`ccm.core.types`):
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
        self._rot = ROT_AXES_2D if dim == 2 else ROT_AXES_3D
        self._width = sum(len(self._rot) if is_rot else dim for _, is_rot in _VECTORS)
        self._zeros = np.zeros(dim)
        # every row's numbers, float64, end to end: no per-step Python object outlives
        # record(), so the garbage collector has nothing to track (issue #40)
        self._vectors = bytearray()
        self._scalars = array("d")  # t, segment, F_d, contacts per step
        self._signals = array("d")
        self._extras = array("d")
        self._signal_values = _values(self.signal_keys)
        self._extra_values = _values(self.extra_keys)
        self._table: dict[str, np.ndarray] | None = None

    def record(
        self,
        obs: Observation,
        target: TargetSample,
        cmd: Command,
        info: StepInfo,
        signals: Mapping[str, float],
    ) -> None:
        """Append a copy of one control step (the state ``obs`` at which ``cmd`` was
        computed)."""
        d = target.force_dir
        vectors = (
            target.position, target.velocity, obs.position, obs.lin_vel, obs.force, obs.torque,
            info.true_force, info.contact_force, cmd.force, cmd.torque,
            self._zeros if d is None else d,
        )  # fmt: skip
        try:  # contiguous float64 (dtypes equal, not one object): a copy of the bytes
            row = b"".join(vectors) if {v.dtype for v in vectors} == _ONLY_F64 else None
        except (AttributeError, BufferError, TypeError):  # a list; a strided view
            row = None
        if row is None or len(row) != 8 * self._width:
            row = self._converted(vectors)
        self._vectors += row
        self._scalars.extend(
            (obs.t, target.segment, 0.0 if d is None else target.force_mag, info.n_contacts)
        )
        _extend(self._signals, self._signal_values(signals))
        _extend(self._extras, self._extra_values(info.extra))
        self._table = None

    def _converted(self, vectors: Sequence[Any]) -> bytes:
        """The row's vectors as float64 bytes, whatever their type; a vector of the wrong
        length is refused on one line naming its column."""
        out = []
        for (name, is_rot), v in zip(_VECTORS, vectors, strict=True):
            arr = np.asarray(v, dtype=float).reshape(-1)
            want = len(self._rot) if is_rot else self.dim
            if arr.size != want:
                raise ValueError(
                    f"step {len(self)}: {name} has {arr.size} values, the log expects {want}"
                )
            out.append(arr.tobytes())
        return b"".join(out)

    def __len__(self) -> int:
        return len(self._scalars) // 4

    def arrays(self) -> dict[str, np.ndarray]:
        """The recorded columns as a dict of 1-D arrays, in column order."""
        if self._table is None:
            self._table = self._assemble()
        return self._table

    def _assemble(self) -> dict[str, np.ndarray]:
        n = len(self)
        scalars = np.frombuffer(self._scalars, dtype=_F64).reshape(n, 4).copy()
        out: dict[str, np.ndarray] = {"t": scalars[:, 0], "segment": scalars[:, 1]}
        block = np.frombuffer(self._vectors, dtype=_F64).reshape(n, self._width).copy()
        col = 0
        for name, is_rot in _VECTORS:
            for a in self._rot if is_rot else AXES[: self.dim]:
                out[f"{name}_{a}"] = block[:, col]
                col += 1
        out["force_target_N"] = scalars[:, 2]
        out["n_contacts"] = scalars[:, 3]
        out.update(_table(self.signal_keys, self._signals, n))
        out.update((f"truth_{k}", v) for k, v in _table(self.extra_keys, self._extras, n).items())
        return out

    @property
    def columns(self) -> list[str]:
        """Column names in file order."""
        return list(self.arrays())

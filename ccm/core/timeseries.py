"""Trial time series on disk: one compressed Parquet file per trial (issue #19).

``<run dir>/timeseries/<condition>/trial_NNN.parquet`` holds the columns of
:class:`ccm.core.records.TrialRecorder` (one row per control step). Columns are float32 except
:data:`FLOAT64_COLUMNS`; metrics and ``summary.json`` are computed from the in-memory float64
arrays, so the on-disk precision never changes a result. ``experiment.timeseries`` chooses
which trials are written (:data:`MODES`, :func:`keep_trial`): a full paper run's CSVs took
4.4 GB, most of it trials that no figure reads.
"""

from __future__ import annotations

from collections.abc import Mapping
from pathlib import Path
from typing import Any

import numpy as np

from ccm.core.errors import ConfigError, check_choice
from ccm.core.records import atomic_path

#: ``experiment.timeseries``: every trial, the first and last of each condition's phase, none
MODES = ("all", "first_last", "none")
#: columns stored as float64; every other column is float32 (~7 significant digits: enough
#: for logged positions, velocities, forces and gains). Time keeps float64: float32's spacing
#: at t = 100 s is 7.6 us, so 1 ms samples would no longer be evenly spaced to 1e-9 s.
FLOAT64_COLUMNS = frozenset({"t"})
#: a float32's mantissa bits; ``experiment.timeseries_bits`` keeps this many or fewer
FLOAT32_BITS = 23
#: the fewest mantissa bits ``experiment.timeseries_bits`` may keep (2^-9: 0.1 % steps)
MIN_BITS = 8


def check_mode(value: Any) -> str:
    """``experiment.timeseries``, validated: one of :data:`MODES` (else a one-line error)."""
    return check_choice("experiment.timeseries", value, MODES)


def check_bits(value: Any) -> int:
    """``experiment.timeseries_bits``, validated: an integer in [MIN_BITS, FLOAT32_BITS]."""
    if (
        isinstance(value, bool)
        or not isinstance(value, int)
        or not (MIN_BITS <= value <= FLOAT32_BITS)
    ):
        raise ConfigError(
            "experiment.timeseries_bits",
            f"must be an integer from {MIN_BITS} to {FLOAT32_BITS} (float32 mantissa bits "
            f"kept), got {value!r}",
        )
    return int(value)


def round_mantissa(values: np.ndarray, bits: int) -> np.ndarray:
    """``values`` (float32) rounded to nearest with ``bits`` mantissa bits kept, the rest
    zero: a relative error of at most 2^-(bits+1) (18 bits: 1.9e-6, about 5.7 significant
    digits), and the zeroed low bytes compress to almost nothing. Integers below 2^(bits+1)
    stay exact; inf and NaN stay as they are."""
    a = np.ascontiguousarray(values, dtype=np.float32)
    drop = FLOAT32_BITS - int(bits)
    if drop <= 0:
        return a
    u = a.view(np.uint32)
    mask = np.uint32((0xFFFFFFFF >> drop) << drop)
    rounded = ((u + np.uint32(1 << (drop - 1))) & mask).view(np.float32)
    return np.where(np.isfinite(a) & np.isfinite(rounded), rounded, a)


def keep_trial(mode: str, index: int, count: int) -> bool:
    """Whether trial ``index`` (0-based) of a phase of ``count`` trials is written: every
    trial (``all``), the phase's first and last (``first_last``), or none (``none``)."""
    if mode == "all":
        return True
    if mode == "first_last":
        return index in (0, count - 1)
    return False


def trial_path(run_dir: Path, condition: str, trial: int) -> Path:
    """``<run_dir>/timeseries/<condition>/trial_NNN.parquet``: one trial's time series."""
    return Path(run_dir) / "timeseries" / condition / f"trial_{int(trial):03d}.parquet"


def write_timeseries(path: Path, table: Mapping[str, np.ndarray], bits: int = FLOAT32_BITS) -> None:
    """Write equal-length 1-D columns to ``path`` as Parquet, atomically: float64 for
    :data:`FLOAT64_COLUMNS`, float32 rounded to ``bits`` mantissa bits (:func:`round_mantissa`)
    otherwise, zstd (level 9) over byte-stream-split floats (measured on paper trials: 6-7x
    smaller than the ``%.9g`` CSV it replaced at 23 bits, ~10 ms per trial; 18 bits take 17 %
    less again)."""
    import pyarrow as pa
    import pyarrow.parquet as pq

    columns = {
        name: np.asarray(v, dtype=np.float64)
        if name in FLOAT64_COLUMNS
        else round_mantissa(np.asarray(v, dtype=np.float32), bits)
        for name, v in table.items()
    }
    with atomic_path(Path(path)) as tmp:
        pq.write_table(
            pa.table(columns), tmp, compression="zstd", compression_level=9,
            use_dictionary=False, use_byte_stream_split=True,
        )  # fmt: skip


def read_timeseries(path: Path) -> dict[str, np.ndarray]:
    """Read a file of :func:`write_timeseries`: column name -> 1-D array, in file order and
    the stored dtype (float64 for :data:`FLOAT64_COLUMNS`, float32 otherwise)."""
    import pyarrow.parquet as pq

    table = pq.read_table(path)
    return {name: table.column(name).to_numpy() for name in table.column_names}

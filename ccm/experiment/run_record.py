"""Run records a lab can trust (issue #19): a lock and a config check on every run directory,
no stale temporary files. Interrupts: :mod:`ccm.experiment.interrupts`.

Every run (a single run, or each job of a sweep) opens its run directory with
:func:`open_record`, which, before anything is written there:

1. takes an exclusive, non-blocking ``flock`` on ``<dir>/.lock`` (the holder's pid inside): a
   second run into the directory is refused (:class:`RecordRefused`) and writes nothing;
2. compares the SHA-256 of the composed, resolved config (:func:`config_digest`) with the one
   the directory's record was made with (``config.sha256``; for a record from before the hash,
   its ``.hydra/config.yaml``). Another config is refused, and so is a directory that holds
   files but no ccm record (issue #39), unless ``force``, which moves the old contents aside
   to ``<dir>.replaced-<timestamp>`` (nothing is deleted) and starts over;
3. removes the temporary files that killed atomic writes left
(:func:`ccm.core.records.atomic_path`).

Hydra's own ``.hydra/`` writing is off (``hydra.output_subdir: null`` in configs/config.yaml):
:meth:`Record.write_hydra` writes the same three files once the lock is held, so a refused run
leaves the directory as it was.
"""

from __future__ import annotations

import errno
import fcntl
import hashlib
import json
import os
import time
from collections.abc import Iterator
from contextlib import AbstractContextManager, contextmanager, suppress
from dataclasses import dataclass
from datetime import datetime
from pathlib import Path
from typing import Any

from omegaconf import DictConfig, OmegaConf

from ccm.core.errors import to_plain
from ccm.core.records import read_json_object, write_atomic

LOCK_NAME = ".lock"
HASH_NAME = "config.sha256"
HYDRA_DIR = ".hydra"
#: Hydra's record of a sweep's config, in the sweep directory
MULTIRUN_FILE = "multirun.yaml"
#: "1" while ``ccm run --force`` runs (its jobs may run in other processes: sweep workers)
FORCE_ENV = "CCM_FORCE"
#: a moved-aside record is ``<run dir>.replaced-<timestamp>`` (sweeps skip such directories)
REPLACED = ".replaced-"


class RecordRefused(Exception):
    """A run directory this run may not write (in use, or another config's record): one line."""


def config_digest(cfg: DictConfig) -> str:
    """SHA-256 of the composed config, resolved (``hydra`` excluded: the job config), as JSON
    with sorted keys: the same config gives the same hash in any directory and process."""
    try:
        data: Any = to_plain(cfg)
        text = json.dumps(data, sort_keys=True, separators=(",", ":"), default=str)
    except Exception:  # an unresolvable interpolation fails the run later; hash the text now
        text = OmegaConf.to_yaml(cfg)
    return hashlib.sha256(text.encode("utf-8")).hexdigest()


class RunLock:
    """An exclusive ``flock`` on ``<run_dir>/.lock``, holding the holder's pid; the file is
    removed on release (a run that was killed leaves it, unlocked: the kernel drops the lock)."""

    def __init__(self, run_dir: Path) -> None:
        self.run_dir = Path(run_dir)
        self._fd: int | None = None

    @property
    def path(self) -> Path:
        """The lock file."""
        return self.run_dir / LOCK_NAME

    def acquire(self) -> None:
        """Take the lock without waiting; :class:`RecordRefused` if another process holds it."""
        while True:
            try:
                fd = os.open(self.path, os.O_RDWR | os.O_CREAT, 0o644)
            except OSError as exc:
                raise RecordRefused(
                    f"run directory {self.run_dir}: cannot create its lock file "
                    f"({exc.strerror}); choose a writable directory"
                ) from None
            try:
                fcntl.flock(fd, fcntl.LOCK_EX | fcntl.LOCK_NB)
            except OSError as exc:
                holder = _holder(fd) if exc.errno in (errno.EAGAIN, errno.EACCES) else None
                os.close(fd)
                raise RecordRefused(
                    f"run directory {self.run_dir} is in use by another run ({holder or 'pid ?'})"
                    "; wait for it to end or choose another directory"
                ) from None
            if _same_file(fd, self.path):  # not a file its last holder removed meanwhile
                break
            os.close(fd)
        os.ftruncate(fd, 0)
        os.write(fd, f"{os.getpid()}\n".encode())
        self._fd = fd

    def release(self) -> None:
        """Remove the lock file (while still holding it) and drop the lock."""
        if self._fd is None:
            return
        with suppress(OSError):
            if _same_file(self._fd, self.path):
                self.path.unlink()
        os.close(self._fd)
        self._fd = None


def _holder(fd: int) -> str | None:
    """``pid N`` from a held lock file (its holder writes it just after locking)."""
    for _ in range(5):
        text = os.pread(fd, 32, 0).decode(errors="replace").strip()
        if text.isdigit():
            return f"pid {text}"
        time.sleep(0.02)
    return None


def _same_file(fd: int, path: Path) -> bool:
    try:
        a, b = os.fstat(fd), os.stat(path)
    except OSError:
        return False
    return (a.st_dev, a.st_ino) == (b.st_dev, b.st_ino)


@dataclass
class Record:
    """An open run directory: locked, its config checked (see :func:`open_record`)."""

    run_dir: Path
    cfg: DictConfig
    digest: str
    replaced: Path | None = None  # where ``force`` moved the previous record

    def write_hydra(self, hydra_cfg: Any, overrides: Any) -> None:
        """Write ``config.sha256`` and ``.hydra/`` (config, hydra, overrides: as Hydra would)."""
        write_atomic(self.run_dir / HASH_NAME, self.digest + "\n")
        out = self.run_dir / HYDRA_DIR
        write_atomic(out / "config.yaml", OmegaConf.to_yaml(self.cfg))
        write_atomic(out / "hydra.yaml", OmegaConf.to_yaml(hydra_cfg))
        write_atomic(out / "overrides.yaml", OmegaConf.to_yaml(overrides))


@contextmanager
def open_record(run_dir: Path, cfg: DictConfig, force: bool = False) -> Iterator[Record]:
    """Lock ``run_dir``, check its record's config against ``cfg`` (``force``: move the record
    aside instead), clean stale temporary files; the lock is held until the block ends."""
    run_dir = Path(run_dir)
    run_dir.mkdir(parents=True, exist_ok=True)
    lock = RunLock(run_dir)
    lock.acquire()
    try:
        digest = config_digest(cfg)
        stored = stored_digest(run_dir, cfg)
        replaced = None
        foreign = _foreign_files(run_dir) if stored is None else []
        if foreign or (stored is not None and (force or stored != digest)):
            if not force:
                raise RecordRefused(_refusal(run_dir, foreign))
            replaced, lock = _move_aside(lock)
        clean_stale_temp(run_dir)
        yield Record(run_dir=run_dir, cfg=cfg, digest=digest, replaced=replaced)
    finally:
        lock.release()


def _foreign_files(run_dir: Path) -> list[str]:
    """What a directory without a ccm record holds besides the run's lock and Hydra's job log
    (``<job name>.log``, opened and appended to by Hydra before any ccm code runs)."""
    return sorted(
        p.name for p in run_dir.iterdir()
        if p.name != LOCK_NAME and not (p.suffix == ".log" and p.is_file())
    )  # fmt: skip


def _refusal(run_dir: Path, foreign: list[str]) -> str:
    """The one line that refuses ``run_dir``: another config's record, or files not ccm's."""
    if foreign:
        shown = ", ".join(foreign[:3]) + (", ..." if len(foreign) > 3 else "")
        what = f"holds files that are not a ccm run record ({shown})"
    else:
        what = f"holds a run of another config ({HASH_NAME} differs)"
    return (
        f"run directory {run_dir} {what}; run again with --force to move it aside and start "
        "over, or choose another directory"
    )


def ok_summary(run_dir: Path) -> dict | None:
    """The summary of a run directory that already holds an ``ok`` run, else None."""
    summary = read_json_object(Path(run_dir) / "summary.json")
    return summary if summary is not None and summary.get("status") == "ok" else None


def stored_digest(run_dir: Path, cfg: DictConfig) -> str | None:
    """The config hash ``run_dir``'s record was made with; None if it holds no record. A record
    from before ``config.sha256`` counts as this config's if its ``.hydra/config.yaml`` is."""
    path = run_dir / HASH_NAME
    if path.is_file():
        return path.read_text(encoding="utf-8").strip()
    saved = run_dir / HYDRA_DIR / "config.yaml"
    if saved.is_file():
        same = saved.read_text(encoding="utf-8") == OmegaConf.to_yaml(cfg)
        return config_digest(cfg) if same else "unknown"
    return None


def _move_aside(lock: RunLock) -> tuple[Path, RunLock]:
    """Rename the locked run directory to ``<dir>.replaced-<timestamp>`` and lock a new, empty
    one in its place; returns the new name and the new lock (the old one is released)."""
    run_dir = lock.run_dir
    aside = _aside_name(run_dir)
    os.rename(run_dir, aside)
    lock.run_dir = aside  # the held lock file moved with the directory
    try:
        run_dir.mkdir()
        fresh = RunLock(run_dir)
        fresh.acquire()
    finally:
        lock.release()
    return aside, fresh


def _aside_name(path: Path) -> Path:
    """``<path>.replaced-<timestamp>`` (``-2``, ``-3``, … if taken): where a record moves."""
    stamp = datetime.now().strftime("%Y-%m-%d_%H-%M-%S")
    aside = path.with_name(f"{path.name}{REPLACED}{stamp}")
    n = 1
    while aside.exists():
        n += 1
        aside = path.with_name(f"{path.name}{REPLACED}{stamp}-{n}")
    return aside


def check_sweep_record(sweep_dir: Path, cfg: DictConfig, force: bool) -> Path | None:
    """Before a sweep starts in ``sweep_dir``: the sweep recorded there (``multirun.yaml``,
    Hydra's record of the sweep's config, sweep values left out) must have ``cfg``'s config, so
    an edited config file or another override cannot resume it; :class:`RecordRefused`
    otherwise. ``force`` moves the old ``multirun.yaml`` aside (returned) instead; each job's
    own record is checked when the job opens it (:func:`open_record`)."""
    old = Path(sweep_dir) / MULTIRUN_FILE
    if not old.is_file():
        return None
    try:
        same = config_digest(job_config(OmegaConf.load(old))) == config_digest(job_config(cfg))
    except Exception:  # unreadable: not a record of this config
        same = False
    if same:
        return None
    if not force:
        raise RecordRefused(
            f"sweep directory {sweep_dir} holds a sweep of another config ({MULTIRUN_FILE} "
            "differs); run again with --force to move its records aside and start over, or "
            "choose another directory"
        )
    aside = _aside_name(old)
    os.rename(old, aside)
    return aside


def job_config(cfg: DictConfig) -> DictConfig:
    """``cfg`` without its ``hydra`` node: the config a job's record hashes."""
    return OmegaConf.masked_copy(cfg, [k for k in cfg if k != "hydra"])


def clean_stale_temp(run_dir: Path) -> list[Path]:
    """Remove the temporary files of atomic writes that were killed (``.<name>.<random>.tmp``,
    :func:`ccm.core.records.atomic_path`) anywhere in ``run_dir``; returns the removed paths."""
    removed = []
    for path in sorted(Path(run_dir).rglob(".*.tmp")):
        if path.is_file():
            with suppress(FileNotFoundError):
                path.unlink()
                removed.append(path)
    return removed


@contextmanager
def scoped_env(key: str, value: str) -> Iterator[None]:
    """Set the environment variable ``key`` within the block (processes started meanwhile,
    e.g. sweep workers, inherit it); its previous value, or absence, comes back afterwards."""
    saved = os.environ.get(key)
    os.environ[key] = value
    try:
        yield
    finally:
        if saved is None:
            os.environ.pop(key, None)
        else:
            os.environ[key] = saved


def forcing(force: bool) -> AbstractContextManager[None]:
    """``ccm run --force`` (or not) for the jobs run within the block (:func:`forced`)."""
    return scoped_env(FORCE_ENV, "1" if force else "0")


def forced() -> bool:
    """Whether this job runs under ``ccm run --force``."""
    return os.environ.get(FORCE_ENV) == "1"

"""Clean interrupts (issue #19): SIGINT and SIGTERM end a run with one line and a record.

Inside :func:`interrupts_raise`, SIGINT and SIGTERM raise :class:`RunInterrupted` (once; a
second signal is ignored while the record is written), so a run ends with one line, a
``summary.json`` whose status is ``interrupted`` (:func:`interrupted_summary`) and exit code
128 + the signal number (130, 143), instead of a traceback (SIGINT) or silently (SIGTERM).

A local sweep's jobs run in joblib/loky worker processes. The launching process forwards the
signal to them and waits until they have recorded their jobs (:func:`stop_local_workers`);
a worker exits once its interrupted job is recorded, and quietly when signalled between jobs
(:func:`job_signals`). On Linux a worker also gets SIGTERM when its launcher dies, even by
SIGKILL (:func:`die_with_launcher`), rather than finish its job unwatched; elsewhere the run
directory's lock (:mod:`ccm.experiment.run_record`) keeps a re-run out of a job an orphan still
runs.
"""

from __future__ import annotations

import os
import signal
import sys
import time
from collections.abc import Callable, Iterator
from contextlib import AbstractContextManager, contextmanager, suppress
from pathlib import Path
from typing import Any

from omegaconf import DictConfig, OmegaConf

#: the pid of the process that runs ``ccm run`` (set by it): any other process running a job
#: is a sweep worker, which exits once its interrupted job is recorded
LAUNCHER_PID_ENV = "CCM_LAUNCHER_PID"
#: how long the launching process waits for interrupted sweep workers to record their jobs
WORKER_GRACE_S = 10.0


class RunInterrupted(BaseException):
    """SIGINT or SIGTERM arrived. A BaseException, like KeyboardInterrupt, so that no
    ``except Exception`` records it as a failure; ``trials`` are the trials that finished."""

    def __init__(self, signum: int) -> None:
        super().__init__(signal.Signals(signum).name)
        self.signum = signum
        self.trials: list[dict[str, Any]] = []

    @property
    def name(self) -> str:
        """``SIGINT`` or ``SIGTERM``."""
        return signal.Signals(self.signum).name

    @property
    def exit_code(self) -> int:
        """The shell's convention: 128 + the signal number (130, 143)."""
        return 128 + self.signum


def interrupted_summary(cfg: DictConfig | None, exc: RunInterrupted) -> dict[str, Any]:
    """The summary.json of an interrupted run: status ``interrupted``, the signal, the cause
    (``error``, as a failed run has) and the trials that finished."""
    n = len(exc.trials)
    return {
        "experiment": OmegaConf.select(cfg, "experiment.name") if cfg is not None else None,
        "status": "interrupted",
        "seed": OmegaConf.select(cfg, "seed") if cfg is not None else None,
        "error": f"interrupted by {exc.name} after {n} finished trial{'s' * (n != 1)}",
        "signal": exc.name,
        "trials": exc.trials,
    }


def record_interrupt(
    run_dir: Path, cfg: DictConfig, exc: RunInterrupted, finished: list[dict[str, Any]]
) -> None:
    """Write the interrupted run's summary.json with its ``finished`` trials, unless the run
    had already written its ``ok`` summary (interrupted after it: the record is whole). The
    temporary file of an atomic write the signal cut short goes (the signal may land between
    the file's creation and the ``try`` that would remove it)."""
    from ccm.core.records import write_json_atomic
    from ccm.experiment.run_record import clean_stale_temp, ok_summary

    clean_stale_temp(run_dir)  # the run holds the directory's lock: no other writer
    exc.trials = finished
    if ok_summary(run_dir) is None:
        write_json_atomic(run_dir / "summary.json", interrupted_summary(cfg, exc))


@contextmanager
def interrupts_raise(
    on_signal: Callable[[int], None] | None = None, *, restore_on_interrupt: bool = True
) -> Iterator[None]:
    """Within the block, the first SIGINT or SIGTERM calls ``on_signal(signum)`` and raises
    :class:`RunInterrupted`; later ones are ignored. The previous handlers come back afterwards,
    unless the block ends interrupted and not ``restore_on_interrupt``: a job then records its
    interruption with signals still ignored (the outermost block, ``ccm run``'s, restores them).
    Outside the main thread (no signals there): does nothing."""
    import threading

    if threading.current_thread() is not threading.main_thread():
        yield
        return

    def handler(signum: int, _frame: Any) -> None:
        for sig in (signal.SIGINT, signal.SIGTERM):
            signal.signal(sig, signal.SIG_IGN)
        if on_signal is not None:
            on_signal(signum)
        raise RunInterrupted(signum)

    previous = {sig: signal.signal(sig, handler) for sig in (signal.SIGINT, signal.SIGTERM)}
    previous_hook = sys.unraisablehook
    sys.unraisablehook = _keep_swallowed(previous_hook)
    restore = True
    try:
        yield
        raise_if_interrupted()  # swallowed after the last trial boundary
    except RunInterrupted:
        restore = restore_on_interrupt
        raise
    finally:
        sys.unraisablehook = previous_hook
        _SWALLOWED.clear()
        for sig, old in previous.items() if restore else ():
            signal.signal(sig, old)


#: a :class:`RunInterrupted` that Python could not propagate: the signal arrived inside a
#: callback whose exceptions are "ignored" (a cffi ``ffi.gc`` destructor such as pymunk's
#: space, a ``__del__``, a weakref callback). Process-wide, as the signal disposition it
#: stands for; only :func:`interrupts_raise` fills and empties it.
_SWALLOWED: list[RunInterrupted] = []


def _keep_swallowed(
    previous: Callable[[Any], object],
) -> Callable[[Any], object]:
    """A ``sys.unraisablehook`` that keeps a swallowed :class:`RunInterrupted` for
    :func:`raise_if_interrupted` (without the "Exception ignored" traceback: the run still
    ends with one line) and passes every other unraisable exception to ``previous``."""

    def hook(unraisable: Any) -> None:
        if isinstance(unraisable.exc_value, RunInterrupted):
            _SWALLOWED.append(unraisable.exc_value)
        else:
            previous(unraisable)

    return hook


def raise_if_interrupted() -> None:
    """Raise the :class:`RunInterrupted` of a signal whose exception a callback swallowed
    (:data:`_SWALLOWED`), if any: the trial loop calls this at each trial boundary, so such a
    run still ends ``interrupted`` with its finished trials instead of running on to ``ok``."""
    if _SWALLOWED:
        raise _SWALLOWED[0]


def launcher_env() -> AbstractContextManager[None]:
    """Mark this process as the one that runs ``ccm run`` for its jobs, wherever they run
    (sweep workers inherit the environment; :func:`in_worker`)."""
    from ccm.experiment.run_record import scoped_env

    return scoped_env(LAUNCHER_PID_ENV, str(os.getpid()))


@contextmanager
def job_signals(multirun: bool) -> Iterator[None]:
    """Signals around one job: SIGINT and SIGTERM raise :class:`RunInterrupted`
    (:func:`interrupts_raise`). In a sweep worker also: die with the launcher; once an
    interrupted job is recorded, exit (take no further job); between jobs, exit quietly."""
    worker = multirun and in_worker()
    if worker:
        die_with_launcher()
    try:
        with interrupts_raise(restore_on_interrupt=False):
            yield
    except RunInterrupted as exc:
        if worker:
            exit_worker(exc.exit_code)
        raise
    finally:
        if worker:
            quiet_idle_worker()


def in_worker() -> bool:
    """Whether this process runs a sweep job for another one (a joblib/loky worker, a submitit
    job): not the process that ran ``ccm run``."""
    launcher = os.environ.get(LAUNCHER_PID_ENV)
    return launcher is not None and launcher != str(os.getpid())


def die_with_launcher() -> None:
    """Linux: ask the kernel to send this sweep worker SIGTERM when its launcher dies, even by
    SIGKILL; the worker then records its job as interrupted and exits instead of finishing it
    unwatched (a re-run would run it again). A worker whose launcher died before this call
    (its parent is no longer the process that started it) signals itself at once. Elsewhere,
    or when the launcher did not start this process (a cluster job), a no-op: the run
    directory's lock still keeps a re-run out of a job an orphan is running."""
    import multiprocessing

    if not sys.platform.startswith("linux"):
        return
    parent = multiprocessing.parent_process()  # who started this process, alive or not
    if parent is None or str(parent.pid) != os.environ.get(LAUNCHER_PID_ENV):
        return
    import ctypes

    with suppress(Exception):
        ctypes.CDLL(None, use_errno=True).prctl(1, int(signal.SIGTERM))  # PR_SET_PDEATHSIG
    if os.getppid() != parent.pid:  # the launcher died before the prctl could watch it
        os.kill(os.getpid(), signal.SIGTERM)


def exit_worker(code: int) -> None:
    """End a sweep worker whose job was interrupted (and recorded), so that it takes no further
    job; its launcher is being interrupted too."""
    from multiprocessing import util

    with suppress(Exception):  # e.g. tqdm's semaphore: unregistered, not reported as leaked
        util._run_finalizers()
    for stream in (sys.stdout, sys.stderr):
        with suppress(Exception):
            stream.flush()
    os._exit(code)


def quiet_idle_worker() -> None:
    """In a sweep worker between jobs, SIGINT and SIGTERM end the process at once and quietly
    (no KeyboardInterrupt traceback from the worker's loop)."""
    for sig in (signal.SIGINT, signal.SIGTERM):
        signal.signal(sig, lambda signum, _frame: exit_worker(128 + signum))


def stop_local_workers(signum: int, grace_s: float = WORKER_GRACE_S) -> None:
    """Forward ``signum`` to this process's joblib/loky sweep workers, if any, and wait (at
    most ``grace_s``) for them to record their interrupted jobs and exit; joblib then kills
    what is left, so no worker goes on to finish jobs after its launcher has ended."""
    workers = list((getattr(_local_executor(), "_processes", None) or {}).values())
    if not workers:
        return
    from multiprocessing.connection import wait

    for proc in workers:
        with suppress(OSError, AttributeError, TypeError):
            os.kill(proc.pid, signum)
    pending = [p.sentinel for p in workers if getattr(p, "sentinel", None) is not None]
    deadline = time.monotonic() + grace_s
    while pending and (left := deadline - time.monotonic()) > 0:
        ready = wait(pending, timeout=left)
        pending = [s for s in pending if s not in ready]


def _local_executor() -> Any:
    """joblib's loky executor in this process (a local sweep's workers), or None."""
    module = sys.modules.get("joblib.externals.loky.reusable_executor")
    return getattr(module, "_executor", None)

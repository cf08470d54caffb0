"""Learned controller state on disk: ``state/<condition>.json`` of a run (issue #5).

Format (JSON, never pickle)::

    {"format": "ccm-learned-state", "version": 1, "controller_type": "avic_modes",
     "condition": "<name>", "trials": 5, "state": {...Controller.state_dict()...}}

``trials`` counts the trials the state has learned from, over all the runs it came through.
Every problem when loading is a one-line :class:`ConfigError` named ``init_from``.
"""

from __future__ import annotations

import json
import math
from collections.abc import Iterable
from pathlib import Path
from typing import Any

from ccm.control.base import Controller
from ccm.control.registry import CONTROLLERS
from ccm.core.errors import ConfigError, check_regular_file, leaves
from ccm.core.records import write_json_atomic

STATE_FORMAT = "ccm-learned-state"
STATE_VERSION = 1


def controller_type(controller: Controller) -> str:
    """The registry name (``controller.type``) of a controller; a plugin's import path."""
    if controller.type_name is not None:
        return controller.type_name
    cls = type(controller)
    path = f"{cls.__module__}:{cls.__qualname__}"
    for name, target in CONTROLLERS.items():
        if target == path:
            return name
    return path  # a plugin: its import path


def save_states(state_dir: Path, items: Iterable[tuple[str, Controller, int]]) -> None:
    """Write ``<state_dir>/<condition>.json`` for each (condition, controller, trials) whose
    controller learns (:meth:`Controller.state_dict` is not None)."""
    for name, controller, trials in items:
        state = controller.state_dict()
        if state is None:
            continue
        record = {
            "format": STATE_FORMAT,
            "version": STATE_VERSION,
            "controller_type": controller_type(controller),
            "condition": name,
            "trials": trials,
            "state": state,
        }
        write_json_atomic(state_dir / f"{name}.json", record, compact=True)


def load_states(init_from: Any, items: Iterable[tuple[str, Controller]]) -> dict[str, int]:
    """Load ``<init_from>/state/<condition>.json`` into each (condition, controller); return
    the trials each loaded state had learned from. Conditions whose controller does not learn
    need no file."""
    if not isinstance(init_from, str) or not init_from:
        raise ConfigError("init_from", f"must be a previous run directory, got {init_from!r}")
    root = Path(init_from)
    if not root.is_dir():
        raise ConfigError("init_from", f"{init_from!r} is not a directory (a previous run's)")
    state_dir = root / "state"
    found = sorted(p.stem for p in state_dir.glob("*.json")) if state_dir.is_dir() else []
    prior: dict[str, int] = {}
    for name, controller in items:
        path = state_dir / f"{name}.json"
        if path.exists() or path.is_symlink():  # there, but perhaps a directory or a FIFO
            check_regular_file("init_from", path)
        if not path.is_file():
            if controller.state_dict() is None:
                continue
            hint = f"found: {', '.join(found)}" if found else "the run saved no learned state"
            raise ConfigError(
                "init_from", f"no learned state for condition {name!r} in {state_dir} ({hint})"
            )
        prior[name] = _load_state_file(path, controller)
    return prior


def _load_state_file(path: Path, controller: Controller) -> int:
    """Check a state file and load it into ``controller``; return its ``trials``."""
    try:
        data = json.loads(path.read_text(encoding="utf-8"))
    except (OSError, UnicodeDecodeError, json.JSONDecodeError) as exc:
        raise ConfigError("init_from", f"{path}: not a readable JSON file ({exc})") from None
    fmt = data.get("format") if isinstance(data, dict) else None
    if fmt != STATE_FORMAT:
        raise ConfigError("init_from", f"{path}: format {fmt!r} is not {STATE_FORMAT!r}")
    if data.get("version") != STATE_VERSION:
        raise ConfigError(
            "init_from", f"{path}: version {data.get('version')!r}, this ccm reads {STATE_VERSION}"
        )
    saved, ours = data.get("controller_type"), controller_type(controller)
    if saved != ours:
        raise ConfigError(
            "init_from", f"{path}: state of controller type {saved!r}, this condition's is {ours!r}"
        )
    trials = data.get("trials")
    if isinstance(trials, bool) or not isinstance(trials, int) or trials < 0 or "state" not in data:
        raise ConfigError("init_from", f"{path}: needs 'trials' (an integer >= 0) and 'state'")
    _check_numbers(path, data["state"])
    try:
        controller.load_state_dict(data["state"])
    except ConfigError as exc:
        problem = exc.problem if exc.key == "init_from" else str(exc)
        raise ConfigError("init_from", f"{path}: {problem}") from None
    return trials


#: the largest magnitude a learned state holds (issue #39: a state of 1e300s failed the run
#: later without naming the file). Saved states of the paper run reach 2e5 (sample counts);
#: covariances, gains and weights are far smaller
STATE_LIMIT = 1e12


def _check_numbers(path: Path, state: Any) -> None:
    """Every number in a state file finite and within ±:data:`STATE_LIMIT`, else one line
    naming the file and the entry."""
    for where, _, value in leaves(state, "state"):
        if isinstance(value, int | float) and not isinstance(value, bool):
            if not (math.isfinite(value) and abs(value) <= STATE_LIMIT):
                raise ConfigError(
                    "init_from", f"{path}: {where} = {value!r}: a learned state holds finite "
                    f"numbers within ±{STATE_LIMIT:g}; the file is damaged or not a ccm state",
                )  # fmt: skip

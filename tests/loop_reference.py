"""Runs pinned by ``tests/test_loop_reference.py`` and how their metrics are computed.

Run as a script (``python tests/loop_reference.py OUT.json``) to regenerate the pins; do that
only for a deliberate change of results, never to make a speed-up pass.
"""

from __future__ import annotations

import json
import sys
import tempfile
from collections.abc import Callable, Sequence
from pathlib import Path
from typing import Any

from omegaconf import DictConfig

#: name -> overrides; fast mode, so each run takes seconds
RUNS: dict[str, list[str]] = {
    "smoke": ["experiment=smoke", "experiment.fast=true"],
    "avic_porridge": [
        "experiment=single", "task=porridge_stirring", "controller=avic", "experiment.fast=true",
    ],
    "avic_modes_changing_surface_2d": [
        "experiment=single", "task=changing_surface_2d", "controller=avic_modes",
        "experiment.fast=true",
    ],
}  # fmt: skip


def run_metrics(composer: Callable[[Sequence[str]], DictConfig], name: str) -> dict[str, Any]:
    """The summary's per-condition and per-trial metrics of run ``name`` (numbers only)."""
    from ccm.runner import run_experiment

    overrides = RUNS[name]
    with tempfile.TemporaryDirectory() as tmp:
        summary = run_experiment(
            composer(overrides),
            lambda extra: composer([*overrides, *extra]),
            Path(tmp),
            show_progress=False,
        )
    trials = {
        f"{t['condition']}/{t['phase']}/{t['trial']}": {
            k: v for k, v in t.items() if k not in ("condition", "phase", "trial")
        }
        for t in summary["trials"]
    }
    return {"conditions": summary["conditions"], "trials": trials}


def main(out: str) -> None:
    from hydra import compose, initialize_config_dir

    from ccm.cli import config_dir

    with initialize_config_dir(str(config_dir()), version_base="1.3", job_name="ref"):
        ref = {n: run_metrics(lambda o: compose("config", overrides=list(o)), n) for n in RUNS}
    Path(out).write_text(json.dumps(ref, indent=1, allow_nan=False) + "\n", encoding="utf-8")


if __name__ == "__main__":
    main(sys.argv[1])

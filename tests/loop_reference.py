"""Runs pinned by ``tests/test_loop_reference.py`` and how their metrics are computed.

Run as a script (``python tests/loop_reference.py OUT.json [NAME ...]``) to regenerate the
pins (of NAMEs only, if given); do that only for a deliberate change of results, never to make
a speed-up pass.
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
    # PyBullet, with contact: the table (from 3.38 s) and H4's boxes; pinned after the
    # tool-point Jacobian fix and the Pinocchio model terms (issue #20)
    "table_wall_3d": [
        "experiment=single", "sim=pybullet3d", "task=table_wall",
        "controller=fixed_impedance_medium", "experiment.trials=1", "experiment.max_time_s=5",
    ],
    "h4_collisions_3d": ["experiment=h4_collisions", "experiment.fast=true",
                         "experiment.fast_time_s=3"],
    # the footprint friction of the table patches (sim.patch_mode=footprint) while the tool
    # slides from patch A onto B, with collision anticipation (pinned before its kernel)
    "h4_impactless_3d": ["experiment=h4_impactless", "experiment.fast=true",
                         "experiment.fast_time_s=5"],
}  # fmt: skip


def run_metrics(composer: Callable[[Sequence[str]], DictConfig], name: str) -> dict[str, Any]:
    """The summary's per-condition and per-trial metrics of run ``name`` (numbers only)."""
    from ccm.experiment.runner import run_experiment

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


def main(out: str, names: Sequence[str] = ()) -> None:
    """Write the pins of ``names`` (default: every run) to ``out``; the other runs' pins are
    kept from ``out`` if it exists (pin a new run without re-recording the old ones)."""
    from hydra import compose, initialize_config_dir

    from ccm.cli import config_dir

    path = Path(out)
    ref = json.loads(path.read_text(encoding="utf-8")) if path.is_file() else {}
    with initialize_config_dir(str(config_dir()), version_base="1.3", job_name="ref"):
        for n in names or RUNS:
            ref[n] = run_metrics(lambda o: compose("config", overrides=list(o)), n)
    ref = {n: ref[n] for n in RUNS if n in ref}
    path.write_text(json.dumps(ref, indent=1, allow_nan=False) + "\n", encoding="utf-8")


if __name__ == "__main__":
    main(sys.argv[1], sys.argv[2:])

"""Run any experiment: the condition × phase × trial loop (``run_experiment`` of
:mod:`ccm.experiment.runner`) or, for ``experiment.kind`` other than ``trials``, the analysis
that kind names.

The analyses sit above the runner: some of them build components or run trials through it
(:mod:`ccm.analyses.h3_data`, :mod:`ccm.analyses.forward_model_study`), so the runner cannot
dispatch to them without importing upward. The CLI and the tests call :func:`run`.
"""

from __future__ import annotations

from collections.abc import Callable
from pathlib import Path
from typing import Any

from omegaconf import DictConfig

from ccm.experiment.components import ANALYSIS_KINDS, ComposeFn
from ccm.experiment.runner import run_experiment

Analysis = Callable[[DictConfig, ComposeFn, Path], dict[str, Any]]


# Each analysis is imported when its kind runs: together they pull in scikit-learn, CasADi
# and the GP code (~2-4 s), which a trial-loop run does not need.
def _h3() -> Analysis:
    from ccm.analyses.h3 import (
        run_h3,  # seed A §4.4: offline SVM + GP baseline vs incremental models
    )

    return run_h3


def _mpc_convexity() -> Analysis:
    from ccm.analyses.mpc_convexity import run_convexity  # seed B §5.2, Fig. 4

    return run_convexity


def _gp_contact_models() -> Analysis:
    from ccm.analyses.gp_contact_models import run_gp_contact_models  # seed B §5.3, Fig. 5

    return run_gp_contact_models


def _forward_model_horizon() -> Analysis:
    from ccm.analyses.forward_model_study import run_study  # issue #16: skill against the horizon

    return run_study


def _mpc_table2() -> Analysis:
    from ccm.analyses.mpc_table2 import run_table2  # seed B Table 2 by replay (issue #37)

    return run_table2


#: experiment.kind -> the analysis that kind names (the kinds other than ``trials``)
ANALYSES: dict[str, Callable[[], Analysis]] = {
    "h3": _h3,
    "mpc_convexity": _mpc_convexity,
    "gp_contact_models": _gp_contact_models,
    "forward_model_horizon": _forward_model_horizon,
    "mpc_table2": _mpc_table2,
}
assert set(ANALYSES) == set(ANALYSIS_KINDS), (
    "ccm.experiment.components.ANALYSIS_KINDS names these kinds"
)


def run(cfg: DictConfig, compose: ComposeFn, out_dir: Path, **loop: Any) -> dict[str, Any]:
    """Run ``cfg``'s experiment into ``out_dir`` and return its summary: the analysis of
    ``experiment.kind``, or the trial loop (``loop``: the keywords of
    :func:`ccm.experiment.runner.run_experiment`, e.g. ``show_progress``, ``finished``)."""
    load = ANALYSES.get(cfg.experiment.get("kind", "trials"))
    if load is not None:
        return load()(cfg, compose, out_dir)
    return run_experiment(cfg, compose, out_dir, **loop)

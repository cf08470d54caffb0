"""The contracts of :mod:`ccm.core.protocols` hold for what ccm builds: every forward-model kind
is a ForwardModel, planned and re-timed patterns are Patterns, every extra metric is a
Metric (issue #21)."""

from __future__ import annotations

import inspect

import numpy as np
import pytest

from ccm.core.protocols import ForwardModel, Metric, Pattern
from ccm.core.types import TargetSample
from ccm.experiment.components import build_components
from ccm.learn.mixtures.forward_model import FORWARD_MODELS, make_forward_model
from ccm.metrics.trial import EXTRA_METRICS


@pytest.mark.parametrize("kind", FORWARD_MODELS)
def test_every_forward_model_kind_is_a_forward_model(kind: str) -> None:
    model = make_forward_model({"kind": kind})
    assert isinstance(model, ForwardModel)
    assert not model.ready  # a fresh model has nothing to predict with


def test_an_object_without_predict_is_not_a_forward_model() -> None:
    class Half:
        horizon_s = 0.1
        ready = True

        def update(self, s_prev: np.ndarray, d_now: np.ndarray) -> None: ...

    assert not isinstance(Half(), ForwardModel)


@pytest.mark.parametrize(
    "overrides",
    [
        ["task=multi_spring", "controller=avic"],
        ["sim=pybullet3d", "task=h4_collisions", "controller=avic_anticipation"],
    ],
)
def test_planned_and_prepared_patterns_are_patterns(composer, overrides: list[str]) -> None:
    """The task's P and what a controller's ``prepare`` returns (re-timed for anticipation)
    both sample a TargetSample and have a duration."""
    comp = build_components(composer(overrides))
    try:
        comp.sim.reset(seed=0)
        comp.controller.reset(comp.task.dim, comp.sim.control_dt)
        prepared = comp.controller.prepare(
            comp.task.pattern, comp.task.contacts, np.random.default_rng(0)
        )
        for pattern in (comp.task.pattern, prepared):
            assert isinstance(pattern, Pattern)
            assert isinstance(pattern.sample(0.1), TargetSample)
            assert pattern.duration > 0.0
    finally:
        comp.sim.close()


@pytest.mark.parametrize("name", list(EXTRA_METRICS))
def test_every_extra_metric_takes_log_dim_params(name: str) -> None:
    metric: Metric = EXTRA_METRICS[name]
    assert list(inspect.signature(metric).parameters) == ["log", "dim", "params"]

"""H1 in seed A §4.1's protocol (issue #38): ``h1_forward_model_one_step`` runs without F/T
noise, and every forward model predicts exactly one control step ahead. It must not be
rounded to 0 steps or left at the 50 ms of ``h1_forward_model``, its robustness row."""

from __future__ import annotations

import math

import numpy as np
import pytest

from ccm.core.errors import to_plain
from ccm.core.types import Observation, TargetSample
from ccm.experiment.components import build_components, check_experiment, plan_experiment
from ccm.experiment.trial import run_trial
from ccm.learn.mixtures.forward_model import magnitudes, make_forward_model
from ccm.metrics.trial import force_prediction_metrics


def _plan(composer, experiment: str) -> list:
    overrides = [f"experiment={experiment}"]
    cfg = composer(overrides)
    trials = check_experiment(cfg)["trials"]
    return plan_experiment(cfg, lambda extra: composer([*overrides, *extra]), trials)


@pytest.mark.parametrize(("experiment", "steps", "noise"), [
    ("h1_forward_model_one_step", 1, 0.0),  # seed A §4.1: one step, noiseless
    ("h1_forward_model", 50, 0.05),  # the robustness row: 50 ms, 0.05 N
])  # fmt: skip
def test_every_condition_predicts_its_protocols_horizon(
    composer, experiment: str, steps: int, noise: float
) -> None:
    """Every condition x phase of each H1 forward-model experiment: the controller's forecast
    spans ``steps`` control steps and the F/T sensor has the protocol's noise."""
    plan = _plan(composer, experiment)
    assert {c.name for c, _ in plan} == {
        "fixed_gmm", "incremental", "fixed_gmm_avic", "incremental_stiff"
    }  # fmt: skip
    for _, phases in plan:
        for _, comp in phases:
            try:
                assert comp.sim.control_dt == pytest.approx(0.001)
                assert comp.controller.forecast.horizon == steps
                assert comp.controller.model.horizon_s == pytest.approx(steps * 0.001)
                assert comp.sim.sensor.config.force_noise_std == (noise, noise)
            finally:
                comp.sim.close()


def _obs(k: int) -> Observation:
    """A force ramp of 0.1 N per step at constant speed (noiseless, as in §4.1's world)."""
    f = 1.0 + 0.1 * k + 0.02 * math.sin(0.3 * k)
    return Observation(
        0.001 * k, np.zeros(2), np.zeros(1), np.array([0.1, 0.0]), np.zeros(1),
        np.array([-f, 0.0]), np.zeros(1),
    )  # fmt: skip


def test_the_incremental_condition_predicts_the_next_control_step(composer) -> None:
    """The ``incremental`` condition's AVIC, built from the experiment's config, driven step
    by step: the force it logs as predicted for step t is its model's prediction from S_{t-1}
    (a twin model fed the same pairs [S_{t-1}, D_t] gives the same value), and persistence
    is ||F_{t-1}||, one step back (0.1 N below on the ramp, not 5 N as at 50 ms)."""
    overrides = ["experiment=h1_forward_model_one_step", "controller.ff_direction=measured"]
    comp = build_components(composer(overrides))  # the condition's config
    comp.sim.close()
    avic = comp.controller
    twin = make_forward_model(to_plain(composer(overrides).controller.forward_model), "twin")
    target = TargetSample(0.0, np.zeros(2), np.zeros(2), np.zeros(2), np.zeros(1))
    expected: float | None = None  # the twin's prediction of ||F_t||, made at step t - 1
    prev: np.ndarray | None = None
    checked = 0
    for k in range(300):
        o = _obs(k)
        avic.step(o, target)
        s = avic.signals()
        now = magnitudes(o.lin_vel, o.ang_vel, o.force, o.torque)
        if math.isnan(s["pred_force_N"]):  # no model yet: nothing predicted, no persistence
            assert math.isnan(s["persist_force_N"]) and expected is None
        else:
            assert s["persist_force_N"] == pytest.approx(prev[2], rel=1e-12)
            assert now[2] - s["persist_force_N"] == pytest.approx(
                0.1 + 0.02 * (math.sin(0.3 * k) - math.sin(0.3 * (k - 1))), abs=1e-9
            )
            assert s["pred_force_N"] == pytest.approx(expected, rel=1e-6, abs=1e-9)
            checked += 1
        if prev is not None:
            twin.update(prev, now[2:4])  # X_t = [S_{t-1}, D_t]
        expected = float(twin.predict(now)[0]) if twin.ready else None
        prev = now
    assert checked > 250


def test_a_real_trial_scores_the_prediction_one_step_back(composer) -> None:
    """A short real trial of the ``incremental_stiff`` condition (pymunk, noiseless sensor):
    the persistence the metrics compare with is the measured ||F|| of the previous control
    step, and the model's logged prediction error is what force_prediction scores."""
    plan = _plan(composer, "h1_forward_model_one_step")
    comp = dict((c.name, phases) for c, phases in plan)["incremental_stiff"][0][1]
    try:
        a = run_trial(comp, 0, 0.5).arrays()
    finally:
        comp.sim.close()
    f = np.hypot(a["force_x"], a["force_y"])
    persist = a["persist_force_N"]
    ok = np.isfinite(a["pred_force_N"])  # from the step the model can predict
    assert ok.sum() > 400 and not ok[0]
    assert np.array_equal(np.isfinite(persist), ok)
    np.testing.assert_allclose(persist[1:][ok[1:]], f[:-1][ok[1:]], rtol=1e-6, atol=1e-9)
    rmse = float(np.sqrt(np.mean((a["pred_force_N"][ok] - f[ok]) ** 2)))
    out = force_prediction_metrics(a, 2, {"unseen_above_Nspm": 80.0})
    assert out["force_pred_rmse_N"] == pytest.approx(rmse)

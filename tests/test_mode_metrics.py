"""Contact-mode metrics and figures (seed A §4.3, H2) on hand-built logs with known answers."""

from __future__ import annotations

from collections.abc import Callable, Sequence
from pathlib import Path
from types import SimpleNamespace

import numpy as np
import pytest
from omegaconf import DictConfig

from ccm.core.errors import ConfigError
from ccm.metrics.modes import KNOWN, MODE_METRIC_KEYS, NEW, mode_metrics, true_surface_ids
from ccm.metrics.trial import EXTRA_METRICS
from ccm.plots.run import figure_inputs, write_figures

DT = 0.001
PARAMS = {"transition_pre_s": 0.05, "transition_tolerance_s": 0.25, "high_stiffness_Npm": 1650.0}
S0, S1 = 0.3, 0.6  # friction of two surfaces


def make_log(n: int, surfaces: Sequence[tuple[int, float]]) -> dict[str, np.ndarray]:
    """A log of ``n`` steps; ``surfaces``: (from step, friction), −1 = out of contact.

    The controller starts in mode −1 with no decision, at K = 300 N/m.
    """
    mu = np.full(n, -1.0)
    for start, value in surfaces:
        mu[start:] = value
    zeros = np.zeros(n)
    log = {
        "t": np.arange(n) * DT,
        "truth_surface_friction": mu,
        "truth_contact": (mu >= 0).astype(float),
        "mode": np.full(n, -1.0),
        "mode_trigger": zeros.copy(),
        "mode_event": zeros.copy(),
        "mode_confidence": np.full(n, np.nan),
        "mode_second_confidence": np.full(n, np.nan),
        "mode_collecting": zeros.copy(),
        "stiffness_Npm": np.full(n, 300.0),
    }
    for prefix in ("pos", "target_pos", "target_vel", "vel", "force", "force_dir"):
        for a in "xy":
            log[f"{prefix}_{a}"] = zeros.copy()
    return log


def decide(
    log: dict[str, np.ndarray],
    trigger: int,
    step: int,
    mode: int,
    kind: int = KNOWN,
    conf: float = 0.9,
    second: float = 0.1,
    release: int | None = None,
) -> None:
    """Trigger at ``trigger``, collect until ``step``, decide ``mode`` there; K_max from the
    trigger until ``release`` (default: the decision step). Apply decisions in time order."""
    log["mode_trigger"][trigger] = 1.0
    log["mode_collecting"][trigger:step] = 1.0
    log["mode_event"][step] = float(kind)
    log["mode"][step:] = mode
    log["mode_confidence"][step:] = conf
    log["mode_second_confidence"][step:] = second
    log["stiffness_Npm"][trigger : step if release is None else release] = 3000.0


def three_patch_log(lag: int = 0) -> dict[str, np.ndarray]:
    """S0 from step 500, S1 from 1500, S0 again from 2500; every change detected correctly,
    each trigger and decision ``lag`` and ``lag + 100`` steps after it (0: at once)."""
    log = make_log(3000, [(500, S0), (1500, S1), (2500, S0)])
    batch = 100 if lag else 0
    decide(log, 500 + lag, 500 + lag + batch, 0, NEW, conf=0.0, second=np.nan)
    decide(log, 1500 + lag, 1500 + lag + batch, 1, NEW, conf=0.2, second=0.0)
    decide(log, 2500 + lag, 2500 + lag + batch, 0, KNOWN, conf=0.95, second=0.05)
    return log


LOWPASS = {"lowpass_hz": 30.0}


def test_registered_as_extra_metric() -> None:
    assert EXTRA_METRICS["modes"] is mode_metrics


def test_true_surface_ids_by_first_appearance() -> None:
    mu = np.array([-1.0, 0.6, 0.6 + 1e-9, 0.3, np.nan, 0.6, 0.15, 0.3])
    np.testing.assert_array_equal(true_surface_ids(mu), [-1, 0, 0, 1, -1, 0, 2, 1])


def test_perfect_detection() -> None:
    m = mode_metrics(three_patch_log(), 2, PARAMS)
    assert m["n_true_transitions"] == 2
    assert m["n_detected_transitions"] == 2  # the first contact's assignment is not one
    assert m["transition_recall"] == 1.0
    assert m["transition_precision"] == 1.0
    assert m["mode_accuracy"] == 1.0
    assert m["false_new_modes"] == 0
    assert m["n_modes_total"] == 2
    # margins: 0 - 0 (NaN second counts 0), 0.2 - 0, 0.95 - 0.05
    assert m["mean_confidence_margin"] == pytest.approx(0.9)  # known-mode decisions only


def test_detection_lag_costs_accuracy_not_recall() -> None:
    m = mode_metrics(three_patch_log(lag=3), 2, PARAMS)
    assert m["transition_recall"] == 1.0
    assert m["transition_precision"] == 1.0
    # steps with a mode: 603..2999 (2397); wrong: the old mode over 1500..1602 and 2500..2602
    assert m["mode_accuracy"] == pytest.approx((2397 - 206) / 2397)
    assert m["false_new_modes"] == 0


def test_missed_transition() -> None:
    log = make_log(3000, [(500, S0), (1500, S1), (2500, S0)])
    decide(log, 500, 500, 0, NEW)
    decide(log, 1500, 1500, 1, NEW)  # S1 -> S0 at 2500 is never noticed
    m = mode_metrics(log, 2, PARAMS)
    assert m["n_true_transitions"] == 2
    assert m["n_detected_transitions"] == 1
    assert m["transition_recall"] == 0.5
    assert m["transition_precision"] == 1.0
    assert m["mode_accuracy"] == pytest.approx(2000 / 2500)  # mode 1 on S0 for 500 steps


def test_spurious_detection_and_false_new_mode_on_same_surface() -> None:
    log = make_log(3000, [(500, S0), (1500, S1)])
    decide(log, 500, 500, 0, NEW)
    decide(log, 1503, 1603, 1, NEW)
    decide(log, 2000, 2100, 2, NEW)  # nothing changed: S1 still
    m = mode_metrics(log, 2, PARAMS)
    assert m["n_true_transitions"] == 1
    assert m["n_detected_transitions"] == 2
    assert m["transition_recall"] == 1.0
    assert m["transition_precision"] == 0.5
    # mode 1 (lower id) owns S1, so mode 2 owns nothing and all its steps are wrong
    assert m["false_new_modes"] == 1
    assert m["mode_accuracy"] == pytest.approx((2500 - 103 - 900) / 2500)


@pytest.mark.parametrize(
    ("offset_steps", "matched"),
    [(-60, False), (-40, True), (0, True), (240, True), (260, False)],
)
def test_matching_window(offset_steps: int, matched: bool) -> None:
    """A detection matches when its trigger is within [t_true - 0.05 s, t_true + 0.25 s]."""
    log = make_log(3000, [(500, S0), (1500, S1)])
    decide(log, 500, 500, 0, NEW)
    decide(log, 1500 + offset_steps, 1600 + offset_steps, 1, NEW)
    m = mode_metrics(log, 2, PARAMS)
    assert m["n_detected_transitions"] == 1
    assert m["transition_recall"] == (1.0 if matched else 0.0)
    assert m["transition_precision"] == (1.0 if matched else 0.0)


def test_one_to_one_matching() -> None:
    """Two detections in the window of one true transition: only one of them matches."""
    log = make_log(3000, [(500, S0), (1500, S1)])
    decide(log, 500, 500, 0, NEW)
    decide(log, 1500, 1550, 1, NEW)
    decide(log, 1560, 1610, 0, KNOWN)
    m = mode_metrics(log, 2, PARAMS)
    assert m["n_detected_transitions"] == 2
    assert m["transition_recall"] == 1.0
    assert m["transition_precision"] == 0.5


def test_false_new_mode_on_revisited_surface() -> None:
    log = make_log(3000, [(500, S0), (1500, S1), (2500, S0)])
    decide(log, 500, 500, 0, NEW)
    decide(log, 1500, 1500, 1, NEW)
    decide(log, 2500, 2500, 2, NEW)  # S0 again, but taken for a new mode
    m = mode_metrics(log, 2, PARAMS)
    assert m["transition_recall"] == 1.0  # the timing is right: 1 -> 2 is a detected change
    assert m["transition_precision"] == 1.0
    assert m["false_new_modes"] == 1
    assert m["mode_accuracy"] == pytest.approx(2000 / 2500)
    assert m["n_modes_total"] == 3


def test_anomaly_classified_as_current_mode_is_not_a_transition() -> None:
    log = make_log(2000, [(500, S0)])
    decide(log, 500, 600, 0, NEW)
    decide(log, 1000, 1100, 0, KNOWN, conf=0.8, second=0.3)  # a spike, back to mode 0
    m = mode_metrics(log, 2, PARAMS)
    assert m["n_true_transitions"] == 0
    assert m["n_detected_transitions"] == 0
    assert m["transition_recall"] is None
    assert m["transition_precision"] is None
    assert m["mode_accuracy"] == 1.0
    assert m["false_new_modes"] == 0


def test_first_contact_and_touchdown_after_lift_off_are_not_transitions() -> None:
    log = make_log(3000, [(500, S0), (1500, -1.0), (1700, S0)])
    decide(log, 503, 603, 0, NEW)
    log["mode"][1500:] = -1.0  # out of contact: no mode
    decide(log, 1703, 1803, 0, KNOWN)  # back on the same surface
    m = mode_metrics(log, 2, PARAMS)
    assert m["n_true_transitions"] == 0
    assert m["n_detected_transitions"] == 0
    assert m["false_new_modes"] == 0
    # steps with a mode: 603..1499 and 1803..2999, all on S0 in mode 0
    assert m["mode_accuracy"] == 1.0


def test_high_stiffness_time_new_vs_known() -> None:
    log = make_log(3000, [(500, S0), (1100, S1)])
    decide(log, 503, 603, 0, NEW, release=903)  # initial assignment after contact
    decide(log, 1103, 1203, 1, NEW, release=1503)  # new: K_max until the model is learned
    decide(log, 1603, 1703, 1, NEW)  # new, never released before the next trigger (2003)
    log["stiffness_Npm"][1703:2003] = 3000.0
    decide(log, 2003, 2103, 1, KNOWN)  # known: released at the decision
    log["stiffness_Npm"][2050] = 300.0  # a dip during collection does not count
    decide(log, 2500, 2600, 1, KNOWN, release=3000)  # never released: runs to the trial end
    m = mode_metrics(log, 2, PARAMS)
    assert m["high_stiffness_time_initial_s"] == pytest.approx(0.4)
    assert m["high_stiffness_time_new_s"] == pytest.approx((0.4 + 0.4) / 2)
    assert m["high_stiffness_time_known_s"] == pytest.approx((0.1 + 2.999 - 2.5) / 2)


def test_without_mode_signal_everything_is_none() -> None:
    log = make_log(1000, [(500, S0)])
    for k in [k for k in log if k.startswith("mode")]:
        del log[k]
    m = mode_metrics(log, 2, PARAMS)
    assert set(m) == set(MODE_METRIC_KEYS)
    assert all(v is None for v in m.values())


def test_without_truth_only_controller_side_metrics() -> None:
    log = three_patch_log(lag=3)
    del log["truth_surface_friction"], log["truth_contact"]
    m = mode_metrics(log, 2, PARAMS)
    assert m["transition_recall"] is None
    assert m["mode_accuracy"] is None
    assert m["false_new_modes"] is None
    assert m["n_detected_transitions"] == 2
    assert m["high_stiffness_time_new_s"] == pytest.approx(0.1)  # S1, a new mode while sliding
    assert m["high_stiffness_time_initial_s"] == pytest.approx(0.1)


def test_config_defaults_are_valid(composer: Callable[..., DictConfig]) -> None:
    params = dict(composer([]).metrics)
    assert mode_metrics(three_patch_log(), 2, params)["transition_recall"] == 1.0
    with pytest.raises(ConfigError, match="metrics.transition_tolerance_s"):
        mode_metrics(three_patch_log(), 2, {**params, "transition_tolerance_s": -1.0})


def test_mode_figures_written(tmp_path: Path) -> None:
    comps = {n: SimpleNamespace(task=SimpleNamespace(dim=2)) for n in ("modal", "fixed")}
    fixed = make_log(3000, [(500, S0)])
    for k in [k for k in fixed if k.startswith("mode")]:
        del fixed[k]
    logs = {"modal": [three_patch_log(), three_patch_log(lag=3)], "fixed": [fixed]}
    trials = [{"condition": "modal", "trial": k} for k in (1, 2, 3)]
    written = write_figures(tmp_path, figure_inputs(comps, LOWPASS, {}), logs, trials)
    names = {p.name for p in written}
    assert {"modes.png", "mode_stiffness_error.png"} <= names
    assert (tmp_path / "modes.png").stat().st_size > 0
    assert (tmp_path / "mode_stiffness_error.png").stat().st_size > 0


def test_no_mode_figures_without_mode_signal(tmp_path: Path) -> None:
    log = make_log(1000, [(500, S0)])
    for k in [k for k in log if k.startswith("mode")]:
        del log[k]
    comps = {"fixed": SimpleNamespace(task=SimpleNamespace(dim=2))}
    written = write_figures(tmp_path, figure_inputs(comps, LOWPASS, {}), {"fixed": [log]})
    assert written
    assert not (tmp_path / "modes.png").exists()
    assert not (tmp_path / "mode_stiffness_error.png").exists()


SPIKE_PARAMS = {**PARAMS, "spike_window_s": 0.3, "spike_quantile": 0.95}


def spike_log(bumps: Sequence[int]) -> dict[str, np.ndarray]:
    """Surface changes at steps 1500 and 2500; a noisy ~1 mm error everywhere, and a 5 mm
    bump 100 steps after each change listed in ``bumps``."""
    log = make_log(3500, [(500, S0), (1500, S1), (2500, S0)])
    rng = np.random.default_rng(0)
    err = 0.001 + 0.0002 * rng.standard_normal(3500)
    for k in bumps:
        err[k + 100 : k + 120] = 0.005
    log["target_pos_x"] = err  # the error lies along x; force_dir is zero (no force axis)
    return log


def test_error_spikes_at_each_surface_change() -> None:
    """Seed A Fig. 10b: a bump after both changes -> frac 1, ratio ~3; after one -> 0.5;
    none -> frac ~0 and ratio ~1 (the window peak is only the noise's)."""
    spikes = EXTRA_METRICS["error_spikes"]
    both = spikes(spike_log([1500, 2500]), 2, SPIKE_PARAMS)
    assert both["error_spike_frac"] == 1.0
    assert both["error_spike_ratio"] > 2.5  # 5 mm against block peaks of ~1.6 mm
    assert spikes(spike_log([1500]), 2, SPIKE_PARAMS)["error_spike_frac"] == 0.5
    none = spikes(spike_log([]), 2, SPIKE_PARAMS)
    assert none["error_spike_frac"] == 0.0 and none["error_spike_ratio"] < 1.3
    bumps_elsewhere = spike_log([])
    bumps_elsewhere["target_pos_x"][800:820] = 0.005  # a spike away from any change
    assert spikes(bumps_elsewhere, 2, SPIKE_PARAMS)["error_spike_frac"] == 0.0


def test_error_spikes_need_truth_and_a_valid_quantile() -> None:
    spikes = EXTRA_METRICS["error_spikes"]
    log = spike_log([1500])
    no_truth = {k: v for k, v in log.items() if k != "truth_contact"}
    none = {"error_spike_frac": None, "error_spike_ratio": None}
    assert spikes(no_truth, 2, SPIKE_PARAMS) == none
    with pytest.raises(ConfigError, match="metrics.spike_quantile"):
        spikes(log, 2, {**SPIKE_PARAMS, "spike_quantile": 1.5})

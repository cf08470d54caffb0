"""H4 collision metrics and the Fig. 16 figure (seed A §4.5.1, issue #5): synthetic logs."""

from __future__ import annotations

import copy
from pathlib import Path
from types import SimpleNamespace
from typing import Any

import numpy as np
import pytest

from ccm.core.errors import ConfigError
from ccm.core.filters import derivatives
from ccm.metrics.contacts import contact_metrics, impact_jerk
from ccm.metrics.trial import EXTRA_METRICS, compute_extra_metrics
from ccm.plots.run import figure_inputs, write_figures
from ccm.tasks.task import load_task

DT = 0.001
T_HIT = 0.3  # s, the tool meets the surface
PARAMS: dict[str, Any] = {
    "lowpass_hz": 30.0,
    "impact_onset_N": 1.0,
    "impact_window_s": 0.05,
    "impact_acc_window_s": [-0.05, 0.2],
}
TABLE = {
    "name": "table", "kind": "collision", "position": (0.0, 0.0, 0.1), "segment_index": 0,
    "normal": (0.0, 0.0, 1.0),
}  # fmt: skip


def drop_log(n: int = 1000, controller: bool = False) -> dict[str, np.ndarray]:
    """A tool moving down at 0.1 m/s hits a surface at T_HIT: an 8 N pulse for 10 ms, then 2 N.

    Segment 0 until 0.5 s, segment 1 after. ``controller`` adds the anticipation signals.
    """
    t = np.arange(n) * DT
    hit = t >= T_HIT - 1e-12
    vz = np.where(hit, 0.0, -0.1)
    fz = np.where(hit, 2.0, 0.0)
    fz[(t >= T_HIT - 1e-12) & (t < T_HIT + 0.01 - 1e-12)] = 8.0
    zeros = np.zeros(n)
    log = {
        "t": t,
        "segment": np.where(t < 0.5 - 1e-12, 0.0, 1.0),
        "vel_x": zeros,
        "vel_y": zeros,
        "vel_z": vz,
        "pos_x": zeros,
        "pos_y": zeros,
        "pos_z": np.where(hit, 0.1, 0.1 + 0.1 * (T_HIT - t)),  # m: reaches z = 0.1 at T_HIT
        "true_force_x": zeros,
        "true_force_y": 0.3 * np.ones(n),  # off-normal force: ignored by n·F
        "true_force_z": fz,
    }
    if controller:
        alpha = np.zeros(n)
        alpha[200:350] = 0.5  # 0.15 s of transition phase
        event = np.zeros(n)
        event[[302, 700]] = [1.0, 2.0]
        log.update(transition_alpha=alpha, collision_event=event, pattern_rate=np.ones(n))
    return log


LOWPASS = {"lowpass_hz": 30.0}


def test_onset_impact_force_and_acceleration() -> None:
    log = drop_log()
    out = contact_metrics(log, 3, {**PARAMS, "task_contacts": [TABLE]})
    k = int(round(T_HIT / DT))
    assert out["contact_time_s_table"] == pytest.approx(T_HIT)
    assert out["impact_force_N_table"] == pytest.approx(8.0)
    assert out["peak_impact_force_N"] == pytest.approx(8.0)
    vel = np.column_stack([log["vel_x"], log["vel_y"], log["vel_z"]])
    acc = np.linalg.norm(derivatives(vel, DT, 30.0)[0], axis=1)
    expected = float(np.max(acc[k - 50 : k + 201]))
    assert out["impact_acc_mps2_table"] == pytest.approx(expected)
    assert out["peak_impact_acc_mps2"] == pytest.approx(expected)
    # a 0.1 m/s stop through a 30 Hz first-order filter: peak ≈ 0.1 m/s × 2π·30 Hz / e-ish
    assert 5.0 < expected < 0.1 * 2 * np.pi * 30.0
    assert out["transition_time_s"] == 0.0  # no transition_alpha column: no contact handling
    assert out["n_collision_events"] is None
    assert all(v is None or type(v) is float for v in out.values())


def test_onset_is_a_rise_over_the_segment_start_level() -> None:
    log = drop_log()
    log["true_force_z"] = log["true_force_z"] + 5.0  # a constant press from the start
    out = contact_metrics(log, 3, {**PARAMS, "task_contacts": [TABLE]})
    assert out["contact_time_s_table"] == pytest.approx(T_HIT)
    assert out["impact_force_N_table"] == pytest.approx(13.0)
    assert out["impact_force_error_N_table"] == pytest.approx(5.0)  # |13 - F_d 8|
    below = contact_metrics(
        log, 3, {**PARAMS, "impact_force_target_N": 20.0, "task_contacts": [TABLE]}
    )
    assert below["impact_force_error_N_table"] == pytest.approx(7.0)  # |13 - 20|
    out = contact_metrics(log, 3, {**PARAMS, "impact_onset_N": 9.0, "task_contacts": [TABLE]})
    assert out["contact_time_s_table"] is None
    assert out["impact_force_N_table"] is None
    assert out["impact_force_error_N_table"] is None
    assert out["peak_impact_force_N"] is None


def test_controller_signals_and_stable_keys() -> None:
    wall = {
        "name": "wall", "kind": "collision", "position": (0.5, 0.0, 0.1), "segment_index": 1,
        "normal": (-1.0, 0, 0),
    }  # fmt: skip
    skipped = [
        {
            "name": "patch",
            "kind": "impactless",
            "position": (0.0, 0.0, 0.1),
            "segment_index": 0,
            "normal": (0.0, 0.0, 1.0),
        },
        {"name": "nosegment", "kind": "collision", "segment_index": None, "normal": (0, 0, 1)},
    ]
    contacts = [TABLE, wall, *skipped]
    out = contact_metrics(drop_log(controller=True), 3, {**PARAMS, "task_contacts": contacts})
    assert out["transition_time_s"] == pytest.approx(0.15)
    assert out["n_collision_events"] == 2.0
    assert out["contact_time_s_wall"] is None  # no force along -x in segment 1
    assert not any(k.startswith(("impact_", "contact_time")) and k.endswith(("patch", "nosegment"))
                   for k in out)  # fmt: skip
    assert out["contact_error_m_patch"] is None  # no beliefs reported: no belief metrics
    # a trial cut before segment 1 gives the same keys, with None
    short = contact_metrics(drop_log(400), 3, {**PARAMS, "task_contacts": contacts})
    assert set(short) == set(out)
    assert short["impact_force_N_wall"] is None
    assert short["impact_force_N_table"] == pytest.approx(8.0)


def test_search_stops_at_the_next_contacts_segment() -> None:
    log = drop_log()
    log["segment"] = np.where(log["t"] < 0.2, 0.0, 1.0)  # the hit happens in segment 1
    second = dict(TABLE, name="second", segment_index=1)
    out = contact_metrics(log, 3, {**PARAMS, "task_contacts": [TABLE, second]})
    assert out["contact_time_s_table"] is None
    assert out["contact_time_s_second"] == pytest.approx(T_HIT)


def test_registered_and_task_contacts_reach_the_metric() -> None:
    assert EXTRA_METRICS["contacts"] is contact_metrics
    task = load_task(TASK, 0.001)
    comp = SimpleNamespace(task=task)
    cfg = SimpleNamespace(metrics=PARAMS)
    out = compute_extra_metrics(["contacts"], drop_log(), comp, cfg)
    assert out["contact_time_s_floor"] == pytest.approx(T_HIT)
    assert out["impact_force_N_floor"] == pytest.approx(8.0)


TASK: dict[str, Any] = {
    "name": "t",
    "dim": 3,
    "start": [0.0, 0.0, 0.1],
    "orientation": [1.0, 0.0, 0.0, 0.0],
    "scene": {},
    "pattern": [
        {"type": "line", "name": "down", "to": [0.0, 0.0, 0.0], "duration": 0.5},
        {"type": "hold", "name": "press", "duration": 0.5},
    ],
    "contacts": [
        {
            "name": "floor",
            "position": [0.0, 0.0, 0.1],
            "kind": "collision",
            "segment": "down",
            "normal": [0.0, 0.0, 2.0],
        },
        {"name": "patch", "position": [0.0, 0.0, 0.0], "kind": "impactless"},
    ],
}


def test_task_contact_fields_load() -> None:
    task = load_task(TASK, 0.001)
    assert task.contacts[0] == {"name": "floor", "position": (0.0, 0.0, 0.1), "kind": "collision"}
    assert task.contact_annotations == (
        {"segment": "down", "segment_index": 0, "normal": (0.0, 0.0, 1.0)},
        {"segment": None, "segment_index": None, "normal": None},
    )


@pytest.mark.parametrize(
    ("key", "value", "fragment"),
    [
        ("normal", [0.0, 0.0, 0.0], "nonzero"),
        ("normal", [0.0, 1.0], "length 3"),
        ("segment", "nope", "unknown pattern segment 'nope'"),
        ("segment", 3, "segment name"),
    ],
)
def test_bad_contact_fields(key: str, value: Any, fragment: str) -> None:
    cfg = copy.deepcopy(TASK)
    cfg["contacts"][0][key] = value
    with pytest.raises(ConfigError, match=fragment) as err:
        load_task(cfg, 0.001)
    assert err.value.key == f"task.contacts[0].{key}"


def test_h4_tasks_annotate_every_collision(composer: Any) -> None:
    for name in ("h4_collisions", "h4_contact_learning"):
        task = load_task(composer([f"task={name}"]).task, 0.001)
        for c, a in zip(task.contacts, task.contact_annotations, strict=True):
            if c["kind"] == "collision":
                assert a["segment_index"] is not None and a["normal"] is not None, c["name"]


def plot_log(controller: bool = False) -> dict[str, np.ndarray]:
    """:func:`drop_log` plus the columns every run figure reads."""
    log = drop_log(controller=controller)
    n = len(log["t"])
    for a in "xyz":
        for p in ("pos", "target_pos", "target_vel", "force_dir"):
            log[f"{p}_{a}"] = np.zeros(n)
        log[f"force_{a}"] = log[f"true_force_{a}"]
    log["stiffness_Npm"] = np.full(n, 300.0)
    return log


def test_contact_figures_written(tmp_path: Path) -> None:
    patch = {"name": "b", "kind": "impactless", "position": (0.0, 0.0, 0.12)}
    task = SimpleNamespace(dim=3, contacts=(patch,))
    comps = {n: SimpleNamespace(task=task) for n in ("full", "baseline")}
    logs = {"full": [plot_log(True), plot_log(True)], "baseline": [plot_log(), plot_log()]}
    trials = [
        {"condition": c, "trial": k, "transition_time_s": 0.1}
        for c in ("full", "baseline")
        for k in (1, 2)
    ]
    written = write_figures(tmp_path, figure_inputs(comps, LOWPASS, {}), logs, trials)
    names = {p.name for p in written}
    assert {"contact_transitions.png", "contact_transitions_last.png"} <= names
    assert "patch_transitions.png" in names  # Figs 19-20: the task has an impact-less contact
    assert (tmp_path / "contact_transitions.png").stat().st_size > 0
    assert (tmp_path / "contact_transitions_last.png").stat().st_size > 0


def test_no_contact_figures_outside_h4(tmp_path: Path) -> None:
    comps = {"fixed": SimpleNamespace(task=SimpleNamespace(dim=3, contacts=()))}
    written = write_figures(tmp_path, figure_inputs(comps, LOWPASS, {}), {"fixed": [plot_log()]})
    assert written
    assert not (tmp_path / "contact_transitions.png").exists()


def test_onset_search_starts_near_the_surface() -> None:
    """A force rise along the normal while the tool is still far from the surface (friction
    building up as a slide starts) is not the onset (``impact_near_m``)."""
    log = drop_log()
    far = (log["t"] >= 0.05) & (log["t"] < 0.25)  # 2.5-2 cm above the surface
    log["true_force_z"] = log["true_force_z"] + np.where(far, 1.5, 0.0)
    out = contact_metrics(log, 3, {**PARAMS, "task_contacts": [TABLE], "impact_near_m": 0.01})
    assert out["contact_time_s_table"] == pytest.approx(T_HIT)


def test_onset_from_the_normal_part_when_logged() -> None:
    """Friction along the normal that is high at the near step and falls before the touch
    (a tool slowing down and softening within ``impact_near_m``) hides the onset in the true
    force; its normal part (``truth_normal_force_*``) shows it, and the impact force is still
    the true force along the normal."""
    log = drop_log()
    t = log["t"]
    friction = np.where(t < 0.25, 13.0, 3.0) * (t < T_HIT - 1e-12)  # sliding resistance
    log["true_force_z"] = log["true_force_z"] + friction
    out = contact_metrics(log, 3, {**PARAMS, "task_contacts": [TABLE]})
    assert out["contact_time_s_table"] is None  # the level at the near step was 13 N
    zeros = np.zeros_like(t)
    log.update(truth_normal_force_x=zeros, truth_normal_force_y=zeros,
               truth_normal_force_z=np.where(t >= T_HIT - 1e-12, 5.0, 0.0))  # fmt: skip
    out = contact_metrics(log, 3, {**PARAMS, "task_contacts": [TABLE]})
    assert out["contact_time_s_table"] == pytest.approx(T_HIT)
    assert out["impact_force_N_table"] == pytest.approx(8.0)


def test_belief_metrics_from_the_controller_report() -> None:
    """contact_error_m / contact_std_m / approach velocity from the controller's report,
    matched by name against the task's nominal positions."""
    report = {"contacts": [
        {"name": "table", "kind": "collision", "source": "config", "mean": [0.0, 0.003, 0.1],
         "std": 0.004, "approach_velocity": 0.02, "impact_force": 7.5},
        {"name": "new5", "kind": "impactless", "source": "observed", "mean": [0.2, 0.0, 0.1],
         "std": 0.01, "approach_velocity": None, "impact_force": None},
    ]}  # fmt: skip
    out = contact_metrics(
        drop_log(), 3, {**PARAMS, "task_contacts": [TABLE], "controller_report": report}
    )
    assert out["contact_error_m_table"] == pytest.approx(0.003)
    assert out["contact_std_m_table"] == pytest.approx(0.004)
    assert out["approach_velocity_mps_table"] == pytest.approx(0.02)
    assert out["measured_impact_force_N_table"] == pytest.approx(7.5)
    assert out["n_contacts_learned"] == 1.0


def test_contact_table_has_a_row_per_trial_and_believed_contact() -> None:
    from ccm.metrics.contact_beliefs import contact_table

    trial = {"condition": "full", "trial": 1, "pattern_time_s": 20.0, "transition_time_s": 5.0,
             "contact_error_m_table": 0.001, "contact_std_m_table": 0.004,
             "approach_velocity_mps_table": 0.02, "impact_force_N_table": 8.1,
             "measured_impact_force_N_table": 8.0}  # fmt: skip
    base = {"condition": "base", "trial": 1, "contact_error_m_table": None}
    text = contact_table([trial, base])
    assert text is not None and text.count("\n| full | 1 | table |") == 1
    assert "| base |" not in text
    assert contact_table([base]) is None


def test_patch_metrics_look_near_the_surface_boundary() -> None:
    """Impact-less contacts: peak acceleration/jerk only where the tool is within
    patch_window_m of the boundary, and the region of the nearest learned belief."""
    n = 1000
    t = np.arange(n) * DT
    x = 0.4 + 0.1 * t  # 0.1 m/s along +x, crossing the boundary x = 0.45 at t = 0.5 s
    vx = np.full(n, 0.1)
    vx[(t > 0.2) & (t < 0.21)] = 0.2  # a jolt far from the boundary: not counted
    vx[(t > 0.5) & (t < 0.505)] = 0.12  # a small one at the boundary
    zeros = np.zeros(n)
    log = {"t": t, "segment": zeros, "pos_x": x, "pos_y": zeros, "pos_z": zeros,
           "vel_x": vx, "vel_y": zeros, "vel_z": zeros, "true_force_x": zeros,
           "true_force_y": zeros, "true_force_z": zeros}  # fmt: skip
    patch = {"name": "b", "kind": "impactless", "position": (0.45, 0.0, 0.0)}
    report = {"contacts": [{"name": "new4", "kind": "impactless", "mean": [0.452, 0.0, 0.0],
                            "std": 0.01, "region_m": 0.03}]}  # fmt: skip
    params = {**PARAMS, "patch_window_m": 0.03, "task_contacts": [patch]}
    out = contact_metrics(log, 3, {**params, "controller_report": report})
    acc = np.linalg.norm(derivatives(np.column_stack([vx, zeros, zeros]), DT, 30.0)[0], axis=1)
    inside = np.abs(x - 0.45) <= 0.03
    assert out["patch_peak_acc_mps2_b"] == pytest.approx(acc[inside].max())
    assert out["patch_peak_acc_mps2_b"] < acc.max()  # the far jolt is left out
    assert out["region_m_b"] == pytest.approx(0.03)
    assert contact_metrics(log, 3, params)["region_m_b"] is None  # no beliefs: no region


def switch_log(
    detect_at: float | None, ramp: bool = True, kind: float = 2.0
) -> dict[str, np.ndarray]:
    """The tool slides at 0.1 m/s along +x across a switch at x = 0.45 (t = 0.5 s). The table
    friction ramps 0.2 -> 0.4 from t = 0.3 s (``ramp``; else it steps at 0.5 s); Algorithm 1
    decides mode 1 (was 0) at ``detect_at`` (None: never), a new mode (``kind`` 2) or a known
    one (1)."""
    n = 1000
    t = np.arange(n) * DT
    zeros = np.zeros(n)
    start = 0.3 if ramp else 0.5
    mu = 0.2 + 0.2 * np.clip((t - start) / 0.4, 0.0, 1.0) if ramp else np.where(t >= 0.5, 0.4, 0.2)
    mode, event = zeros.copy(), zeros.copy()
    if detect_at is not None:
        k = int(round(detect_at / DT))
        mode[k:], event[k] = 1.0, kind
    event[100] = 1.0  # a decision for the same mode far before the window: not a detection
    return {"t": t, "segment": zeros, "pos_x": 0.4 + 0.1 * t, "pos_y": zeros, "pos_z": zeros,
            "vel_x": np.full(n, 0.1), "vel_y": zeros, "vel_z": zeros, "true_force_x": zeros,
            "true_force_y": zeros, "true_force_z": zeros, "truth_table_friction": mu,
            "mode": mode, "mode_event": event}  # fmt: skip


def test_switch_detection_delay_runs_from_the_friction_onset_to_the_mode_change() -> None:
    """Onset = first change of the table friction in the patch window (0.3 s with the ramp,
    the tool point still 2 cm short); delay to Algorithm 1's mode change; censored at the
    window's end (t = 0.8 s, 3 cm past) when nothing is decided there."""
    patch = {"name": "b", "kind": "impactless", "position": (0.45, 0.0, 0.0)}
    params = {**PARAMS, "patch_window_m": 0.03, "task_contacts": [patch]}
    out = contact_metrics(switch_log(0.62), 3, params)
    assert out["switch_onset_s_b"] == pytest.approx(0.301, abs=1.5e-3)
    assert out["switch_detect_delay_s_b"] == pytest.approx(0.62 - 0.301, abs=1.5e-3)
    assert out["switch_detected_b"] == 1.0
    assert out["switch_known_b"] == 0.0  # a new mode
    known = contact_metrics(switch_log(0.62, kind=1.0), 3, params)
    assert known["switch_known_b"] == 1.0 and known["switch_detected_b"] == 1.0
    step = contact_metrics(switch_log(0.62, ramp=False), 3, params)
    assert step["switch_onset_s_b"] == pytest.approx(0.5, abs=1.5e-3)
    assert step["switch_detect_delay_s_b"] == pytest.approx(0.12, abs=1.5e-3)
    missed = contact_metrics(switch_log(None), 3, params)
    assert missed["switch_detected_b"] == 0.0 and missed["switch_known_b"] is None
    assert missed["switch_detect_delay_s_b"] == pytest.approx(0.8 - 0.301, abs=1.5e-3)
    late = contact_metrics(switch_log(0.9), 3, params)  # after the window: not this switch's
    assert late["switch_detected_b"] == 0.0
    no_modes = {k: v for k, v in switch_log(0.62).items() if k not in ("mode", "mode_event")}
    out = contact_metrics(no_modes, 3, params)
    assert out["switch_onset_s_b"] is not None and out["switch_detect_delay_s_b"] is None


def test_post_impact_jerk_is_the_rms_over_a_window_after_each_onset() -> None:
    """Seed A §3.4.1's "jerk in motion after impact" (issue #38 item 5): ‖j‖ = 2 m/s³ with a
    10 m/s³ burst in [0.30, 0.35) s. The window after an onset at 0.3 s (W = 0.2 s, both ends
    in: 201 steps) holds 50 burst steps and 151 others; a second onset at 0.4 s overlaps it,
    and the union [0.3, 0.6] s (301 steps) counts each step once."""
    t = np.arange(1000) * DT
    jerk = np.full(1000, 2.0)
    jerk[300:350] = 10.0
    out = impact_jerk(jerk, t, {"a": 0.3, "b": 0.4, "c": None}, 0.2)
    assert out["impact_rms_jerk_mps3_a"] == pytest.approx(np.sqrt((50 * 100 + 151 * 4) / 201))
    assert out["impact_rms_jerk_mps3_b"] == pytest.approx(2.0)
    assert out["impact_rms_jerk_mps3_c"] is None
    assert out["post_impact_rms_jerk_mps3"] == pytest.approx(np.sqrt((50 * 100 + 251 * 4) / 301))
    assert impact_jerk(jerk, t, {"c": None}, 0.2) == {
        "impact_rms_jerk_mps3_c": None, "post_impact_rms_jerk_mps3": None,
    }  # fmt: skip


def test_contact_metrics_report_the_jerk_after_the_impact() -> None:
    """The drop log's stop at T_HIT: the jerk of the same filtered derivative as the
    acceleration, RMS over [T_HIT, T_HIT + impact_jerk_window_s]."""
    log = drop_log()
    vel = np.column_stack([log["vel_x"], log["vel_y"], log["vel_z"]])
    jerk = np.linalg.norm(derivatives(vel, DT, 30.0)[1], axis=1)
    k = int(round(T_HIT / DT))
    for window, steps in ((0.2, 201), (0.05, 51)):
        params = {**PARAMS, "impact_jerk_window_s": window, "task_contacts": [TABLE]}
        out = contact_metrics(log, 3, params)
        expected = float(np.sqrt(np.mean(jerk[k : k + steps] ** 2)))
        assert out["impact_rms_jerk_mps3_table"] == pytest.approx(expected)
        assert out["post_impact_rms_jerk_mps3"] == pytest.approx(expected)
    # the jerk decays after the stop: a longer window has a lower RMS
    assert (
        contact_metrics(log, 3, {**PARAMS, "task_contacts": [TABLE]})["post_impact_rms_jerk_mps3"]
        < expected
    )
    with pytest.raises(ConfigError, match="impact_jerk_window_s"):
        contact_metrics(log, 3, {**PARAMS, "impact_jerk_window_s": 0.0, "task_contacts": [TABLE]})

"""h4_impactless laid out as seed A Fig. 19 (issue #38 item 4): the surface switches are unknown
in trial 1 and lie outside trial 1's collision regions, so trial 1 crosses them at the plan's
speed under the base controller and there is a spike for the framework to remove.

The criterion (configs/task/h4_impactless.yaml, experiments/h4.md): each switch lies outside
the trial-1 region C of every collision still ahead of it in the plan by at least 7.5 cm from
the contact's nominal position (the 3 cm patch window, the target's <= 1.5 cm lead on the tool,
the Eq. 10/11 blend at the plan's top speed). The regions are the ones the `full` condition's
controller builds (no simulation): its prior, its detection noise, its 3 sigma.
"""

from __future__ import annotations

import numpy as np
import pytest

from ccm.control.registry import make_controller
from ccm.core.errors import to_plain
from ccm.experiment.components import trial_seed
from ccm.tasks.task import load_task

MARGIN_M = 0.075  # m: patch window 0.03 + the target's lead 0.015 + blend 0.2 s x 0.15 m/s
RUN_SEEDS = range(10)  # the seeds the H4-impactless sign tests are judged on (claims.yaml)


def _full(composer):
    """The `full` condition of experiment=h4_impactless, composed as `ccm run` composes it."""
    cfg = composer(["experiment=h4_impactless"])
    overrides = list(cfg.experiment.conditions.full)
    return composer(["experiment=h4_impactless", *overrides])


def _ahead(task) -> list[tuple[dict, list[str]]]:
    """Each switch with the names of the collisions the plan meets after it."""
    cs = task.contacts
    return [
        (c, [d["name"] for d in cs[i + 1 :] if d["kind"] == "collision"])
        for i, c in enumerate(cs)
        if c["kind"] == "impactless"
    ]


def _controller(cfg, task, seed: int):
    """The `full` controller after trial 1's prepare (the runner's generator for trial 1)."""
    ctrl = make_controller(to_plain(cfg.controller))
    ctrl.reset(task.dim, 0.001)
    ctrl.prepare(task.pattern, task.contacts, np.random.default_rng(trial_seed(seed, 1)))
    return ctrl


def _outside_m(belief, point: np.ndarray, sigma_scale: float) -> float:
    """How far ``point`` lies outside C (the sigma_scale ellipsoid of P + R) at least: its
    distance from the belief mean less C's largest semi-axis [m]."""
    s = belief.cov + belief.R
    return float(
        np.linalg.norm(point - belief.mean) - sigma_scale * np.sqrt(np.max(np.linalg.eigvalsh(s)))
    )


def test_the_switches_are_unknown_in_trial_1(composer) -> None:
    cfg = _full(composer)
    task = load_task(cfg.task, control_dt=0.001)
    told = [c["name"] for c in task.contacts if c["kind"] in cfg.controller.anticipation.use_kinds]
    assert told == ["table", "wall", "object"]  # seed A §4.5.2: the collisions only


def test_every_switch_lies_outside_the_nominal_regions_ahead_by_the_margin(composer) -> None:
    """The trial-1 regions centred on the nominal contacts (the vision noise set to zero, the
    prior std kept): every switch at least MARGIN_M outside each region still ahead."""
    cfg = _full(composer)
    ant = cfg.controller.anticipation
    std = ant.init_std if ant.init_std is not None else ant.init_noise_std
    cfg.controller.anticipation.init_std = float(std)
    cfg.controller.anticipation.init_noise_std = 0.0
    task = load_task(cfg.task, control_dt=0.001)
    beliefs = {c.name: c.belief for c in _controller(cfg, task, 0).contact_map.contacts}
    radius = ant.sigma_scale * np.sqrt(std**2 + ant.map.measurement_noise_std**2)
    assert radius == pytest.approx(0.180, abs=5e-4)  # the ~18 cm of issue #38 item 4 (3 x 6 cm)
    for switch, ahead in _ahead(task):
        p = np.asarray(switch["position"], dtype=float)
        assert ahead, switch["name"]
        for name in ahead:
            np.testing.assert_allclose(beliefs[name].mean, next(
                c["position"] for c in task.contacts if c["name"] == name
            ))  # fmt: skip
            out = _outside_m(beliefs[name], p, ant.sigma_scale)
            assert out >= MARGIN_M, (switch["name"], name, out)


def test_trial_1_crosses_the_switches_outside_the_collision_windows(composer) -> None:
    """The regions the controller builds in trial 1 for the run's seeds (vision noise drawn):
    the plan reaches each switch before the Eq. 10 blend of any collision still ahead starts
    (its pass in C, after the plan-order trim, less blend_s). One seed may miss: the claims'
    sign test needs 9 of 10, so two seeds with a switch inside a region would decide them by
    construction. Seed 0's wall belief is drawn 0.17 m (2.9 sigma) towards surface B."""
    cfg = _full(composer)
    blend = float(cfg.controller.anticipation.blend_s)
    task = load_task(cfg.task, control_dt=0.001)
    ts = np.arange(0.0, task.pattern.duration, 0.001)
    path = task.pattern.sample_many(ts)["position"]
    misses: dict[str, list[int]] = {}
    for seed in RUN_SEEDS:
        ctrl = _controller(cfg, task, seed)
        names = [c.name for c in ctrl.contact_map.contacts]
        for switch, ahead in _ahead(task):
            p = np.asarray(switch["position"], dtype=float)
            t_s = float(ts[np.argmin(np.linalg.norm(path - p, axis=1))])
            open_ = [
                names[i]
                for i, phi_c, phi_x, _ in ctrl._slow  # noqa: SLF001 - the trial's passes
                if names[i] in ahead and phi_c - blend <= t_s <= phi_x
            ]
            if open_:
                misses.setdefault(switch["name"], []).append(seed)
    print(f"\nseeds whose trial 1 crosses a switch inside a collision window: {misses}")
    for name, seeds in misses.items():
        assert len(seeds) <= 1, (name, seeds)

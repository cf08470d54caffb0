"""Contract checks over every simulator backend, and the controllers' step-object check in
the scenes where a controller's history shows (issue #21, #40).

* A simulator: the simulator kit (:mod:`ccm.checks.simulator`) in a task's scene.
* A controller: every config passes the contract kit on both backends
  (``tests/test_contract_kit.py``, :mod:`ccm.checks.controller`); here, the controllers whose
  kept history shows only with contacts or a setting are checked for views of the step
  objects over longer runs (:func:`ccm.checks.steps.check_keeps_no_views`).
"""

from __future__ import annotations

import pytest

from ccm.checks.simulator import check_simulator
from ccm.checks.steps import check_keeps_no_views
from ccm.control.registry import make_controller
from ccm.core.errors import to_plain
from ccm.experiment.components import build_components, build_sim_task
from ccm.experiment.user_configs import group_options
from ccm.sim import BACKENDS

#: a task per backend for the checks (2D: springs; 3D: table contact)
TASK = {"pymunk2d": "multi_spring", "pybullet3d": "press_slide_3d", "mujoco3d": "press_slide_3d"}


@pytest.mark.parametrize("backend", list(BACKENDS))
def test_simulator_contract(composer, backend: str) -> None:
    """The simulator kit (:mod:`ccm.checks.simulator`) on each backend in a task's scene
    (``tests/test_contract_kit.py`` runs it in the kit's own worlds)."""
    cfg = composer([f"sim={backend}", f"task={TASK[backend]}", "controller=fixed_impedance"])
    check_simulator(lambda: build_sim_task(cfg)[0], backend)


#: the ``plugin`` config is a template for a controller from outside ccm: checked here with
#: the plugin of ``tests/plugins`` (issue #41)
PLUGIN = "controller._target_=tests.plugins.controllers:PlainPD"


def controllers() -> list[str]:
    return group_options("controller")


def chosen(name: str) -> list[str]:
    """The overrides that select controller config ``name`` (the plugin with its target)."""
    return [f"controller={name}", *([PLUGIN] if name == "plugin" else [])]


#: controllers whose history shows only with contacts or a setting, checked there too, and
#: the steps that takes (h4_impactless, seed 0: the first contact at step 1436). GP-MPC with
#: a force latency kept views of the measured force (caught at step 3: fixed); AVIC with
#: anticipation kept views of targets that the check's window does not reach (copied now)
MORE = [
    ("avic_anticipation", ["task=h4_impactless", "sim=pybullet3d"], 2000),
    ("avic_modes", ["task=changing_surface", "sim=pybullet3d"], 2000),
    # the same two on the other 3-D engine (issue #42: every contract test of pybullet3d)
    ("avic_anticipation", ["task=h4_impactless", "sim=mujoco3d"], 2000),
    ("avic_modes", ["task=changing_surface", "sim=mujoco3d"], 2000),
    ("gp_mpc", ["task=multi_spring", "controller.force_delay_s=0.004"], 400),  # a latency
]


@pytest.mark.parametrize(("name", "where", "steps"), MORE)
def test_a_controller_keeps_no_view_of_the_step_objects(
    composer, name: str, where: list[str], steps: int
) -> None:
    cfg = composer([*chosen(name), *where])
    comp = build_components(cfg)
    try:
        check_keeps_no_views(
            lambda: make_controller(to_plain(cfg.controller)), comp.sim, comp.task.pattern,
            comp.task.contacts, steps=steps, seed=0,
        )  # fmt: skip
    finally:
        comp.sim.close()

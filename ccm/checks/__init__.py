"""The contract kit: checks a controller or a simulator can run against ccm's protocols, in
your own tests (issue #41; the step objects' promise, issue #40)::

    from ccm.checks import check_controller, parametrize_with_checks

    check_controller(lambda: MyController(stiffness=300.0), backends=("pymunk2d",))

    @parametrize_with_checks({"my_ctrl": lambda: MyController(stiffness=300.0)})
    def test_my_controller(check):
        check()

    check_simulator(lambda: MySim.from_config(sim_cfg, scene_cfg, start))

:mod:`ccm.checks.controller` and :mod:`ccm.checks.simulator` list the checks,
:mod:`ccm.checks.worlds` the worlds a controller's run in, :mod:`ccm.checks.steps` the step
objects' check.
"""

from ccm.checks.controller import check_controller, controller_checks, parametrize_with_checks
from ccm.checks.simulator import check_simulator, simulator_checks
from ccm.checks.steps import ContractError, check_keeps_no_views

__all__ = [
    "ContractError",
    "check_controller",
    "check_keeps_no_views",
    "check_simulator",
    "controller_checks",
    "parametrize_with_checks",
    "simulator_checks",
]

"""The contract kit: checks a controller can run against ccm's protocols, in your own tests
(issue #41; the step objects' promise, issue #40)::

    from ccm.checks import check_controller, parametrize_with_checks

    check_controller(lambda: MyController(stiffness=300.0), backends=("pymunk2d",))

    @parametrize_with_checks({"my_ctrl": lambda: MyController(stiffness=300.0)})
    def test_my_controller(check):
        check()

:mod:`ccm.checks.controller` lists the checks, :mod:`ccm.checks.worlds` the worlds they run
in, :mod:`ccm.checks.steps` the step objects' check.
"""

from ccm.checks.controller import check_controller, controller_checks, parametrize_with_checks
from ccm.checks.steps import ContractError, check_keeps_no_views

__all__ = [
    "ContractError",
    "check_controller",
    "check_keeps_no_views",
    "controller_checks",
    "parametrize_with_checks",
]

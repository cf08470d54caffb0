"""The example controller against ccm's contract kit, on both backends."""

from my_controller.ctrl import ForceLimitedImpedance

from ccm.checks import parametrize_with_checks


@parametrize_with_checks({"my_pd": ForceLimitedImpedance}, backends=("pymunk2d", "pybullet3d"))
def test_my_pd_keeps_ccms_promises(check):
    check()

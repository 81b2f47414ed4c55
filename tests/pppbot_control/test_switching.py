"""controller_manager's switch rules (no ROS): strictness, unknown names, interface conflicts."""
from __future__ import annotations

import pytest

from pppbot_control.switching import ControllerInfo, ControllerStatus, Strictness, plan_switch

ACTIVE, INACTIVE = ControllerStatus.ACTIVE, ControllerStatus.INACTIVE
WHEELS = ("left_wheel_joint/velocity", "right_wheel_joint/velocity")


def controllers(drive: ControllerStatus = ACTIVE, other: ControllerStatus = INACTIVE) -> dict[str, ControllerInfo]:
    return {"diff_drive_base_controller": ControllerInfo(drive, WHEELS),
            "other_drive": ControllerInfo(other, WHEELS),
            "joint_broad": ControllerInfo(ACTIVE, ())}


def test_deactivate_then_activate():
    plan = plan_switch(controllers(), [], ["diff_drive_base_controller"], Strictness.STRICT)
    assert plan.ok and plan.deactivate == ("diff_drive_base_controller",) and plan.activate == ()
    plan = plan_switch(controllers(drive=INACTIVE), ["diff_drive_base_controller"], [], Strictness.STRICT)
    assert plan.ok and plan.activate == ("diff_drive_base_controller",)


def test_already_in_the_state_is_no_change():
    plan = plan_switch(controllers(), ["diff_drive_base_controller"], ["other_drive"], Strictness.STRICT)
    assert plan.ok and plan.activate == () and plan.deactivate == ()


def test_strict_fails_on_an_unknown_name_and_changes_nothing():
    plan = plan_switch(controllers(), ["nope"], ["diff_drive_base_controller"], Strictness.STRICT)
    assert not plan.ok and plan.deactivate == () and "nope not loaded" in plan.message


def test_best_effort_skips_an_unknown_name():
    plan = plan_switch(controllers(), ["nope"], ["diff_drive_base_controller"], Strictness.BEST_EFFORT)
    assert not plan.ok  # every name to activate is unknown
    plan = plan_switch(controllers(), [], ["nope", "diff_drive_base_controller"], Strictness.BEST_EFFORT)
    assert plan.ok and plan.deactivate == ("diff_drive_base_controller",)


def test_a_claimed_command_interface_blocks_activation():
    plan = plan_switch(controllers(), ["other_drive"], [], Strictness.STRICT)
    assert not plan.ok and "held by diff_drive_base_controller" in plan.message
    plan = plan_switch(controllers(), ["other_drive"], ["diff_drive_base_controller"], Strictness.STRICT)
    assert plan.ok and plan.activate == ("other_drive",) and plan.deactivate == ("diff_drive_base_controller",)


def test_unset_strictness_is_best_effort_and_a_bad_one_is_refused():
    assert plan_switch(controllers(), [], ["nope", "joint_broad"], 0).ok
    with pytest.raises(ValueError, match="strictness 7"):
        plan_switch(controllers(), [], [], 7)

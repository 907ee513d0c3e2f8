"""What an instance with masked copies lists (``runtime/masks.py``): the joints, limits, grasps
and actions it has, never a copy its count leaves out or an option it did not choose; setting
an absent copy's joint is a typed error; a copy's requirement binds only when the copy exists.
"""

from __future__ import annotations

from typing import Any

import pytest

from grace_dsl.cli.show_cmd import _subtitle
from grace_dsl.runtime.errors import RequirementError, UnknownNameError
from grace_dsl.runtime.verify import _si

pytestmark = pytest.mark.slow  # the `stack` fixture compiles a unit (tests/runtime/conftest.py)


def test_joints_and_limits_list_only_present_copies(stack: Any) -> None:
    for n in (1, 2, 4):
        inst = stack.instantiate(n=n, h=100e-3)
        names = [f"slide[{k}]" for k in range(n)]
        assert list(inst.joints) == names
        assert list(inst.joint_limits()) == names
        assert len(inst.q) == 4  # the compiled input keeps every copy
    assert stack.instantiate(n=1).joint_limits() == {"slide[0]": (0.0, 0.25)}


def test_grasp_and_action_names_hold_the_chosen_option_of_present_copies(stack: Any) -> None:
    inst = stack.instantiate(n=2, kind="ring")
    assert inst.action_names == (
        "handle[0]@ring.pull_out", "handle[0]@ring.push_in",
        "handle[1]@ring.pull_out", "handle[1]@ring.push_in",
        "open[0]", "open[1]",
    )  # fmt: skip
    expected = {f"handle[{k}]@ring.{g}" for k in (0, 1) for g in ("pull", "push")}
    assert set(inst.grasp_names) == expected
    assert all(inst.grasp(g).shape == (4, 4) for g in inst.grasp_names)  # each one answers


def test_setting_an_absent_copys_joint_is_a_typed_error(stack: Any) -> None:
    inst = stack.instantiate(n=2)
    with pytest.raises(UnknownNameError, match=r"no joint 'slide\[2\]' at n = 2.*\[0\], \[1\]"):
        inst.with_joints({"slide[2]": 0.1})
    with pytest.raises(UnknownNameError, match=r"no joint 'slide\[3\]'"):
        stack.instantiate(n=3, h=0.1, joints={"slide[3]": 0.1})
    moved = inst.with_joints(**{"slide[1]": 0.1})
    assert moved.joints == {"slide[0]": 0.0, "slide[1]": 0.1}


def test_reports_show_only_present_joints(stack: Any) -> None:
    inst = stack.instantiate(n=2).with_joints({"slide[1]": 0.05})
    assert _subtitle(inst) == "slide[0] = 0, slide[1] = 0.05"  # eacc show's subtitle
    assert list(_si(inst, {})["joints"]) == ["slide[0]", "slide[1]"]  # a verify failure's values


def test_a_copys_requirement_binds_only_when_it_exists(stack: Any) -> None:
    # four drawers of 200 mm do not fit under 650 mm, three do: the fourth copy's requirement
    # is what fails, and it is absent at n = 3
    assert stack.instantiate(n=3, h=0.2).count("drawer") == 3
    with pytest.raises(RequirementError, match="the drawer fits in the carcass"):
        stack.instantiate(n=4, h=0.2)

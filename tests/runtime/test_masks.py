"""What an instance with masked copies lists (``runtime/masks.py``): the joints, limits, grasps
and actions it has, never a copy its count leaves out or an option it did not choose; setting
an absent copy's joint is a typed error; a copy's requirement binds only when the copy exists.
"""

from __future__ import annotations

from typing import Any

import pytest

from grace_dsl.cli.show_cmd import _subtitle
from grace_dsl.compiler.build import build
from grace_dsl.runtime.errors import RequirementError, UnknownNameError
from grace_dsl.runtime.library import Library
from grace_dsl.runtime.verify import _si

SOURCE = """use primitives.{Cuboid}
use handles.{StraightHandle, RingPull}

concept Stack {
    param n : int in [1, 4] = 2
    param kind : choice{"bar", "ring"} = "bar"
    param h : length in [100mm, 200mm] = 150mm
    shape body = Cuboid(size: (400mm, 4 * h, 300mm))
    for i in 0..n {
        require (i + 1) * h <= 450mm "the drawer fits in the carcass"
        link drawer[i] {
            shape front[i] = Cuboid(size: (380mm, h - 10mm, 18mm)) at trans(0, i * h, 160mm)
            part handle[i] = match kind {
                "bar" => StraightHandle(standoff: 32mm),
                "ring" => RingPull()
            } at trans(0, i * h, 200mm)
        }
        joint slide[i] : prismatic(base -> drawer[i]) axis (0, 0, 1) range [0, 250mm]
        action open[i] = pull along slide[i] using handle[i].pull
    }
}
"""

pytestmark = pytest.mark.slow  # one compile of the unit (CasADi's VM, no C) for the module


@pytest.fixture(scope="module")
def stack(tmp_path_factory: pytest.TempPathFactory) -> Any:
    root = tmp_path_factory.mktemp("masks")
    (root / "stack.eac").write_text(SOURCE, encoding="utf-8")
    result = build([root / "stack.eac"], root / "cache", use_native=False)
    assert result.ok, result.diagnostics
    return Library(result.units, result)["Stack"]


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
    # three drawers of 200 mm do not fit under 450 mm, two do: the third copy's requirement
    # is what fails, and it is absent at n = 2
    assert stack.instantiate(n=2, h=0.2).count("drawer") == 2
    with pytest.raises(RequirementError, match="the drawer fits in the carcass"):
        stack.instantiate(n=3, h=0.2)

"""An Instance is an immutable value: owned read-only arrays, equality and hashing, cheap
derived instances (with_joints, with_pose), and names that collide with the API's arguments."""

from __future__ import annotations

import ast
import math
import timeit
from pathlib import Path

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

import grace_dsl as eac
from grace_dsl.runtime.specs import ActionSpec, GraspSpec, JointSpec


def random_pose(seed: int) -> np.ndarray:
    rng = np.random.default_rng(seed)
    q, _ = np.linalg.qr(rng.normal(size=(3, 3)))
    m = np.eye(4)
    m[:3, :3], m[:3, 3] = q * np.sign(np.linalg.det(q)), rng.normal(size=3)
    return m


# -- immutability


def test_arrays_are_read_only(lib: eac.Library) -> None:
    inst = lib["SunkenDoor"].instantiate(joints={"hinge": 0.3}, rim=0.05)
    for array in (inst.p, inst.q, inst.pose):
        with pytest.raises(ValueError, match="read-only"):
            array[0] = 99.0
    with pytest.raises(AttributeError):
        inst.p = np.zeros_like(inst.p)  # type: ignore[misc]
    assert inst.params["rim"] == pytest.approx(0.05)


def test_editing_the_callers_pose_afterwards_changes_nothing(lib: eac.Library) -> None:
    """Regression: the instance kept the caller's matrix, so editing it moved the instance."""
    m = random_pose(1)
    door = lib["SunkenDoor"].instantiate(pose=m)
    before = door.grasp("handle.pull").copy()
    m[:3, 3] += 5.0
    np.testing.assert_array_equal(door.grasp("handle.pull"), before)
    moved = door.with_pose(m)
    m[:3, 3] -= 5.0
    np.testing.assert_allclose(moved.grasp("handle.pull")[:3, 3], before[:3, 3] + 5.0)


def test_returned_arrays_are_the_callers_to_edit(lib: eac.Library) -> None:
    door = lib["SunkenDoor"].instantiate()
    g = door.grasp("handle.pull")
    g[0, 3] = 42.0  # a fresh array: editing it does not reach the instance's cache
    assert door.grasp("handle.pull")[0, 3] != 42.0
    lo_hi = door.grasp_range("handle.pull")
    assert door.grasps("handle.pull", 3).flags.writeable
    assert door.grasp_range("handle.pull") == lo_hi


# -- equality and hashing


def test_equal_values_are_equal_and_hash_equal(lib: eac.Library) -> None:
    """Regression: ``inst == inst2`` raised ValueError (numpy's ambiguous truth value)."""
    c = lib["SunkenDoor"]
    a = c.instantiate(pose=random_pose(2), joints={"hinge": 0.3}, rim=0.05)
    b = c.instantiate(pose=random_pose(2), joints={"hinge": 0.3}, rim=0.05)
    assert a == b and hash(a) == hash(b) and a is not b
    assert a != c.instantiate(pose=random_pose(2), joints={"hinge": 0.31}, rim=0.05)
    assert a != c.instantiate(pose=random_pose(2), joints={"hinge": 0.3}, rim=0.045)
    assert a != c.instantiate(pose=random_pose(3), joints={"hinge": 0.3}, rim=0.05)
    assert a != lib["RoomDoor"].instantiate()
    assert a != "SunkenDoor"
    assert len({a, b, c.instantiate()}) == 2
    assert {a: 1}[b] == 1


def test_minus_zero_hashes_like_zero(lib: eac.Library) -> None:
    m = np.eye(4)
    m[0, 3] = -0.0
    a, b = lib["SunkenDoor"].instantiate(pose=m), lib["SunkenDoor"].instantiate()
    assert a == b and hash(a) == hash(b)


# -- derived instances


@settings(max_examples=25, deadline=None, derandomize=True)
@given(
    u=st.tuples(st.floats(0, 1), st.floats(0, 1), st.floats(0, 1)),
    seed=st.integers(0, 1000),
)
def test_with_joints_and_with_pose_equal_instantiating(
    lib: eac.Library, u: tuple[float, float, float], seed: int
) -> None:
    chest = lib["ChestOfDrawers"]
    base = chest.instantiate(travel=0.3)
    limits = base.joint_limits()
    joints = {n: lo + t * (hi - lo) for (n, (lo, hi)), t in zip(limits.items(), u)}
    pose = random_pose(seed)
    want = chest.instantiate(pose=pose, joints=joints, travel=0.3)
    got = base.with_joints(joints).with_pose(pose)
    assert got == want and hash(got) == hash(want)
    for name in chest.grasps:
        np.testing.assert_array_equal(got.grasps(name, 5), want.grasps(name, 5))
    for action, spec in chest.actions.items():
        g = want.grasp(spec.using[0] if spec.using else next(iter(chest.grasps)))
        np.testing.assert_array_equal(got.force(action, grasp=g), want.force(action, grasp=g))
    for link in chest.links:
        np.testing.assert_array_equal(got.link_pose(link), want.link_pose(link))
    assert got.joint_limits() == want.joint_limits()


def test_with_joints_keeps_the_other_joints_and_checks_ranges(lib: eac.Library) -> None:
    chest = lib["ChestOfDrawers"].instantiate(joints={"slide1": 0.1})
    moved = chest.with_joints(slide2=0.2)
    assert moved.joints == {"slide1": 0.1, "slide2": 0.2, "slide3": 0.0}
    assert chest.joints["slide2"] == 0.0  # the original is unchanged
    with pytest.raises(eac.ParameterError, match="outside its range"):
        chest.with_joints(slide1=5.0)
    with pytest.raises(eac.UnknownNameError, match="slide1"):
        chest.with_joints(slid1=0.1)
    with pytest.raises(eac.ParameterError, match="rigid"):
        chest.with_pose(np.diag([2.0, 1.0, 1.0, 1.0]))


def test_with_joints_is_cheaper_than_instantiating(lib: eac.Library) -> None:
    """with_joints skips packing and the requirement checks (nine on the chest)."""
    chest = lib["ChestOfDrawers"]
    inst = chest.instantiate()
    joints = {"slide1": 0.1, "slide2": 0.2}

    def best(fn: object) -> float:
        return min(timeit.repeat(fn, number=200, repeat=5))  # type: ignore[arg-type]

    fresh = best(lambda: chest.instantiate(joints=joints, travel=0.3, size=(0.8, 0.78, 0.48)))
    derived = best(lambda: inst.with_joints(joints))
    assert derived < fresh, (derived, fresh)


# -- names that collide with the API's own arguments


def test_parameters_named_like_arguments_go_through_params(poison: eac.Concept) -> None:
    """A parameter ``joints`` or ``pose`` is reachable through ``params=``; keywords keep
    their API meaning."""
    inst = poison.instantiate(
        pose=random_pose(4), joints={"slide": 0.005}, params={"joints": 0.02, "pose": 2.0}
    )
    assert inst.params["joints"] == 0.02 and inst.params["pose"] == 2.0
    assert inst.joints["slide"] == 0.005
    also = poison.instantiate(params={"joints": 0.02}, gain=1.0)
    assert also.params["joints"] == 0.02
    with pytest.raises(eac.ParameterError, match="both"):
        poison.instantiate(params={"gain": 1.0}, gain=2.0)
    with pytest.raises(eac.ParameterError, match="mapping"):
        poison.instantiate(params=[("gain", 1.0)])
    np.testing.assert_array_equal(poison.pack({"joints": 0.02}), [1.0, 1.0, 0.02, 1.0])


def test_free_parameters_named_reference_and_name(poison: eac.Concept) -> None:
    """Regression: a free parameter ``reference`` was taken as the spin reference (a silently
    wrong pose) and one called ``name`` raised TypeError."""
    inst = poison.instantiate(params={"joints": 0.02})
    pose = inst.grasp("far", free={"reference": 1.0, "name": 0.5})
    x = 1e-3 + 1.0 * 0.02  # gain^2 * 1mm + reference * joints
    np.testing.assert_allclose(pose[:3, 3], [x, 0.5e-3, 0.07])
    np.testing.assert_allclose(inst.grasp("far", name=0.5)[:3, 3], [1e-3, 0.5e-3, 0.07])
    # the keyword reference is the spin reference (a rotation), not the free parameter
    with pytest.raises(eac.ParameterError, match="rotation"):
        inst.grasp("far", reference=1.0)
    with pytest.raises(eac.ParameterError, match="both"):
        inst.grasp("far", free={"name": 0.1}, name=0.2)


# -- typed specs


def test_specs_carry_the_meaning_and_read_like_the_manifest(lib: eac.Library) -> None:
    oven = lib["Oven"]
    grasp = oven.grasps["handle.hook"]
    assert isinstance(grasp, GraspSpec) and grasp.mode == "hook" and not grasp.needs_close
    assert grasp["mode"] == grasp.get("mode") == "hook"  # the old dict access
    assert dict(grasp) == next(g for g in oven.entry["grasps"] if g["name"] == "handle.hook")
    turn = oven.actions["dial.turn_on"]
    assert isinstance(turn, ActionSpec) and turn.turns and not turn.fixed_twist
    assert turn.sense == turn["sense"] and turn.sign in (1.0, -1.0)
    hinge = oven.joints["hinge"]
    assert isinstance(hinge, JointSpec) and hinge.turns and hinge.moving
    assert oven.joints["dial.spin"].kind == "continuous"
    assert all(oven.joint_index[n] == i for i, n in enumerate(oven.moving_joints))
    assert set(oven.part_specs) == set(oven.parts)
    assert list(oven.link_specs) == list(oven.links)
    with pytest.raises(TypeError):
        oven.grasps["x"] = grasp  # type: ignore[index]


def test_the_runtime_has_no_import_cycle() -> None:
    """instance imports manipulation; manipulation must not import instance (nor its private
    helpers) except for type checking."""
    path = Path(eac.__file__).parent / "runtime" / "manipulation.py"
    tree = ast.parse(path.read_text())
    for node in tree.body:
        if isinstance(node, ast.If):  # `if TYPE_CHECKING:`
            continue
        for sub in ast.walk(node):
            if isinstance(sub, ast.ImportFrom):
                assert sub.module != "grace_dsl.runtime.instance", ast.dump(sub)


def test_joint_limits_match_the_compiled_function(lib: eac.Library) -> None:
    for name in ("Oven", "ChestOfDrawers", "KnobFaucet"):
        inst = lib[name].instantiate()
        lo, hi = (np.ravel(x) for x in lib[name].function("joint_limits")(inst.p))
        assert list(inst.joint_limits().values()) == list(zip(lo.tolist(), hi.tolist()))
        assert all(math.isinf(b) for a, b in inst.joint_limits().values() if a == -math.inf)

"""Every bad input to the runtime gets a GraceError with a message a user can act on, and
every quantity it returns is finite (issue 9, §6 and §4)."""

from __future__ import annotations

import math
from collections.abc import Callable
from typing import Any

import numpy as np
import pytest
import trimesh
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

import grace_dsl as eac
from grace_dsl.runtime.concept import ParamPacker, ParamSpec
from grace_dsl.runtime.errors import EvaluationError
from grace_dsl.runtime.inputs import (
    MAX_GRASPS,
    MAX_RANK_SAMPLES,
    MAX_RESOLUTION,
    MAX_SAMPLES,
    MAX_STEPS,
)
from grace_dsl.runtime.manipulation import Option

HUGE = 10**400


@pytest.fixture(scope="module")
def door(lib: eac.Library) -> eac.Instance:
    return lib["SunkenDoor"].instantiate(joints={"hinge": 0.4})


def cases(lib: eac.Library, door: eac.Instance) -> list[tuple[str, Callable[[], Any], str]]:
    """The bad inputs of issue 9 §6, each with a fragment of the message it must give."""
    c, g = lib["SunkenDoor"], door.grasp("handle.pull")
    ragged = [[1, 0, 0, 0], [0, 1, 0], [0, 0, 1, 0], [0, 0, 0, 1]]
    return [
        ("parameter 10**400", lambda: c.instantiate(rim=HUGE), "rim must be a number"),
        ("joint 10**400", lambda: c.instantiate(joints={"hinge": HUGE}), "too large"),
        ("free 10**400", lambda: door.grasp("handle.pull", theta=HUGE), "too large"),
        ("with_joints 10**400", lambda: door.with_joints(hinge=HUGE), "too large"),
        ("pose text", lambda: c.instantiate(pose="identity"), "pose must be numbers"),
        ("ragged pose", lambda: c.instantiate(pose=ragged), "pose must be numbers"),
        ("free text", lambda: door.grasp("handle.pull", theta="abc"), "one number"),
        ("free None", lambda: door.grasp("handle.pull", theta=None), "one number"),
        ("force grasp text", lambda: door.force("open", grasp="G"), "grasp must be numbers"),
        ("joint name int", lambda: c.instantiate(joints={1: 0.3}), "names are strings"),
        ("joints not a mapping", lambda: c.instantiate(joints=np.ones(1)), "mapping"),
        ("lib[123]", lambda: lib[123], "strings"),  # type: ignore[index]
        ("lib[list]", lambda: lib[[1]], "strings"),  # type: ignore[index]
        ("grasp name int", lambda: door.grasp(3), "names are strings"),  # type: ignore[arg-type]
        ("rank samples text", lambda: door.rank("open", samples="x"), "whole number"),
        ("rank gripper text", lambda: door.rank("open", gripper="x"), "Gripper"),
        ("mesh resolution 0", lambda: door.mesh(resolution=0), "at least 3"),
        ("number as text", lambda: c.instantiate(rim="0.05"), "not '0.05'"),
        ("number as bytes", lambda: c.instantiate(rim=b"0.05"), "not b'0.05'"),
        ("vector as text", lambda: c.instantiate(size=["0.5", "0.8", "0.02"]), "3 numbers"),
        ("complex", lambda: c.instantiate(rim=0.05 + 0j), "a number"),
        ("sample_surface 10**9", lambda: door.sample_surface(10**9), "limit of 1,000,000"),
        ("grasps 10**9", lambda: door.grasps("handle.pull", 10**9), "limit of 100,000"),
        ("follow 10**9", lambda: door.follow("open", g, to=1.0, steps=10**9), "limit"),
        ("rank 10**9", lambda: door.rank("open", samples=10**9), "limit of 4,096"),
        ("mesh 10**6", lambda: door.mesh(10**6), "limit of 1,024"),
        ("sdf far", lambda: door.sdf([[1e300, 0, 0]]), "within 1e+06 m"),
        ("pose far", lambda: c.instantiate(pose=_far_pose()), "within 1e+06 m"),
        ("reference text", lambda: door.grasps("handle.pull", 2, reference="up"), "numbers"),
        ("reference shape", lambda: door.grasp("handle.pull", reference=np.eye(2)), "rotation"),
        ("seed negative", lambda: door.sample_surface(3, seed=-1), "at least 0"),
        ("follow to text", lambda: door.follow("open", g, to="far"), "one number"),
        ("free not a mapping", lambda: door.grasp("handle.pull", free=[1]), "mapping"),
    ]


def _far_pose() -> np.ndarray:
    m = np.eye(4)
    m[0, 3] = 1e7
    return m


def test_each_bad_input_of_the_issue_gets_a_typed_error(
    lib: eac.Library, door: eac.Instance
) -> None:
    for label, call, text in cases(lib, door):
        with pytest.raises(eac.GraceError) as info:
            call()
        assert text in str(info.value), (label, str(info.value))
        assert len(str(info.value)) < 400, label  # a 10**400 does not flood the message


def test_counts_at_their_limits_are_accepted_cheaply(door: eac.Instance) -> None:
    """The limits are documented numbers, not accidents: the largest allowed count works."""
    assert door.grasps("handle.pull", MAX_GRASPS).shape == (MAX_GRASPS, 4, 4)
    g = door.grasp("handle.pull")
    assert door.follow("open", g, to=1.0, steps=MAX_STEPS).shape == (MAX_STEPS, 4, 4)
    assert (MAX_SAMPLES, MAX_RANK_SAMPLES, MAX_RESOLUTION) == (1_000_000, 4096, 1024)


# -- non-finite formulas (issue 9 §4)


def test_a_nan_joint_range_is_refused_with_its_source(poison: eac.Concept) -> None:
    """sqrt(gain) with gain < 0: the range of `slide` is NaN, which used to let any value in."""
    with pytest.raises(EvaluationError, match=r"joint slide.*poison\.eac"):
        poison.instantiate(gain=-1.0)


def test_a_nan_grasp_range_is_refused_with_its_source(poison: eac.Concept) -> None:
    inst = poison.instantiate(bend=-1.0)
    for call in (
        lambda: inst.grasp_range("far"),
        lambda: inst.grasps("far", 4),
        lambda: inst.grasp("far", name=0.0),
    ):
        with pytest.raises(EvaluationError, match=r"grasp far.*poison\.eac.*bend=-1"):
            call()


def test_overflowing_formulas_raise_instead_of_returning_inf(poison: eac.Concept) -> None:
    """gain = 1e200 squares to inf: poses, forces and paths built on it are refused."""
    inst = poison.instantiate(gain=1e200)
    flap = poison.instantiate().link_pose("flap")
    for call in (
        lambda: inst.grasp("far"),
        lambda: inst.grasps("far", 3),
        lambda: inst.link_pose("flap"),
        lambda: inst.force("turn", grasp=flap),
        lambda: inst.follow("turn", grasp=flap, to=0.1),
        lambda: inst.mesh(8),
        lambda: inst.sdf([[0.0, 0.0, 0.0]]),
        lambda: inst.sample_surface(5),
    ):
        with pytest.raises(EvaluationError, match=r"not finite.*poison\.eac"):
            call()
    assert np.isfinite(inst.twist("turn")).all()  # the axis itself does not overflow


def test_a_continuous_joint_refuses_infinite_values(lib: eac.Library) -> None:
    """A continuous joint's range is (-inf, inf); an infinite value is still refused."""
    faucet = lib["KnobFaucet"]
    with pytest.raises(eac.ParameterError, match="spindle"):
        faucet.instantiate(joints={"spindle": math.inf})
    inst = faucet.instantiate()
    with pytest.raises(eac.ParameterError, match="spindle"):
        inst.with_joints(spindle=-math.inf)
    action = next(a for a, s in faucet.actions.items() if s.opening and s.joint == "spindle")
    g = inst.grasp(faucet.actions[action].using[0] if faucet.actions[action].using else "grip")
    with pytest.raises(eac.ParameterError, match="cannot reach"):
        inst.follow(action, grasp=g, to=math.inf)


def test_on_the_axis_is_still_a_parameter_error(lib: eac.Library) -> None:
    """A grasp on a turning joint's axis has no linear force: that stays a ParameterError
    pointing to twist, not an EvaluationError."""
    bottle = lib["ScrewCapBottle"].instantiate()
    action = next(a for a, s in bottle.concept.actions.items() if s.turns)
    spec = bottle.concept.actions[action]
    g = bottle.grasp(spec.using[0])
    with pytest.raises(eac.ParameterError, match="twist") as info:
        bottle.force(action, grasp=g)
    assert not isinstance(info.value, EvaluationError)


@pytest.mark.parametrize("lo", [math.nan, (0.0, math.nan)])
def test_a_nan_bound_does_not_disable_range_checks(lo: Any) -> None:
    size = 1 if isinstance(lo, float) else 2
    spec = ParamSpec(
        "x", "length", "num" if size == 1 else "vec", "length", size, 0, lo,
        1.0 if size == 1 else (1.0, 1.0), 0.5 if size == 1 else (0.5, 0.5), None, None, "",
    )  # fmt: skip
    value = 0.5 if size == 1 else (0.5, 0.5)
    with pytest.raises(eac.ParameterError, match="outside its range"):
        spec.encode(value)
    with pytest.raises(eac.ParameterError, match="outside its range"):
        ParamPacker.of((spec,)).pack({"x": value}, "C")


# -- random inputs: only GraceErrors, or finite results


SMALL = st.sampled_from([0, 1, 2, 3, -1, -7, 10**9, HUGE, -HUGE, 2**63])
ATOMS = st.one_of(
    st.none(),
    st.booleans(),
    st.text(max_size=4),
    st.binary(max_size=4),
    SMALL,
    st.floats(allow_nan=True, allow_infinity=True),
    st.complex_numbers(max_magnitude=2),
    st.sampled_from(
        [np.eye(4), np.eye(4).tolist(), np.eye(3), np.full((4, 4), np.nan), [[0.0, 0.0, 0.0]]]
    ),
)
NESTED = st.one_of(
    ATOMS,
    st.lists(ATOMS, max_size=4),
    st.tuples(ATOMS, ATOMS, ATOMS),
    st.dictionaries(st.text(max_size=3), ATOMS, max_size=3),
)
JUNK = st.one_of(NESTED, st.lists(NESTED, max_size=4), st.tuples(NESTED, NESTED, NESTED))
NAMES = st.one_of(
    st.sampled_from(["handle.pull", "open", "hinge", "leaf", "rim", "SunkenDoor", "push_edge"]),
    JUNK,
)


def finite(result: Any) -> bool:
    """Every number a call returned is finite."""
    if isinstance(result, np.ndarray):
        return bool(np.isfinite(result).all())
    if isinstance(result, trimesh.Trimesh):
        return bool(np.isfinite(result.vertices).all())
    if isinstance(result, Option):
        return result.pose is None or finite(result.pose)
    if isinstance(result, dict):
        return all(finite(v) for v in result.values())
    if isinstance(result, (tuple, list)):
        return all(finite(v) for v in result)
    if isinstance(result, float):
        return math.isfinite(result)
    return True


def calls(lib: eac.Library, door: eac.Instance, poison: eac.Concept) -> list[Any]:
    c, g = lib["SunkenDoor"], door.grasp("handle.pull")
    return [
        lambda x, y: lib[x],
        lambda x, y: c.instantiate(pose=x),
        lambda x, y: c.instantiate(joints=x),
        lambda x, y: c.instantiate(joints={"hinge": x}),
        lambda x, y: c.instantiate(rim=x, size=y),
        lambda x, y: c.instantiate(params=x),
        lambda x, y: c.instantiate(params={"handle.r_out": x}),
        lambda x, y: poison.instantiate(gain=x).grasp("far"),
        lambda x, y: poison.instantiate(bend=x).grasps("far", 2),
        lambda x, y: poison.instantiate(gain=x).force("turn", grasp=g),
        lambda x, y: door.grasp(x),
        lambda x, y: door.grasp("handle.pull", theta=x),
        lambda x, y: door.grasp("handle.pull", reference=x),
        lambda x, y: door.grasp("handle.pull", free=x),
        lambda x, y: door.grasps(x, y),
        lambda x, y: door.grasps("handle.pull", x, reference=y),
        lambda x, y: door.grasp_range(x),
        lambda x, y: door.grasp_width(x),
        lambda x, y: door.force(x, grasp=y),
        lambda x, y: door.force("open", grasp=x),
        lambda x, y: door.twist(x),
        lambda x, y: door.follow("open", grasp=x, to=y),
        lambda x, y: door.follow("open", grasp=g, to=x, steps=y),
        lambda x, y: door.follow(x, grasp=g, to=1.0),
        lambda x, y: door.rank(x, samples=y),
        lambda x, y: door.rank("open", gripper=x, samples=2),
        lambda x, y: door.rank("open", samples=x, reference=y),
        lambda x, y: door.sdf(x),
        lambda x, y: door.sample_surface(x, seed=y),
        lambda x, y: door.sample_surface(2, seed=x),
        lambda x, y: door.mesh(x),
        lambda x, y: door.link_pose(x),
        lambda x, y: door.with_joints(x),
        lambda x, y: door.with_joints(hinge=x),
        lambda x, y: door.with_pose(x),
    ]


@pytest.mark.slow
@settings(
    max_examples=400,
    deadline=None,
    derandomize=True,
    suppress_health_check=[HealthCheck.too_slow, HealthCheck.function_scoped_fixture],
)
@given(which=st.integers(0, 34), x=NAMES, y=JUNK)
def test_random_inputs_raise_only_grace_errors(
    lib: eac.Library, door: eac.Instance, poison: eac.Concept, which: int, x: Any, y: Any
) -> None:
    call = calls(lib, door, poison)[which]
    try:
        result = call(x, y)
    except eac.GraceError:
        return
    assert finite(result), (which, x, y)


@pytest.mark.parametrize(
    "change",
    [
        {"max_width": "0.08"},
        {"finger_length": HUGE},
        {"finger_width": None},
        {"approach": "down"},
        {"approach": (0, 0, "a")},
        {"approach": [[0, 0, 1]]},
        {"approach_tolerance": None},
        {"approach_tolerance": math.nan},
    ],
)
def test_a_bad_gripper_is_a_parameter_error(change: dict[str, Any]) -> None:
    import dataclasses

    with pytest.raises(eac.ParameterError, match="gripper panda"):
        dataclasses.replace(eac.Gripper.panda(), **change)


@pytest.mark.parametrize("width", ["0.01", None, HUGE, math.nan, -0.01, 0.2])
def test_a_bad_opening_is_a_parameter_error(width: Any) -> None:
    with pytest.raises(eac.ParameterError):
        eac.Gripper.panda().finger_boxes(width)


def test_the_limits_are_the_documented_ones() -> None:
    from pathlib import Path

    from grace_dsl.runtime.inputs import MAX_COORDINATE

    text = (Path(__file__).parents[2] / "docs" / "api.md").read_text()
    section = text[text.index("**Limits.**") :][:1200]
    for limit in (MAX_GRASPS, MAX_SAMPLES, MAX_STEPS, MAX_RANK_SAMPLES, MAX_RESOLUTION):
        assert f"{limit:,}" in section, limit
    assert MAX_COORDINATE == 1e6 and "within 1e6 m" in section


def test_a_nested_list_is_no_number_and_no_grasp_is_no_pose(lib) -> None:  # type: ignore[no-untyped-def]
    """Found by bench/bench_adversarial.py: [[0.1]] was read as 0.1; grasp=None as the identity."""
    fridge = lib["Refrigerator"]
    with pytest.raises(eac.ParameterError, match="nested list"):
        fridge.instantiate(handle_y=[[0.1]])
    inst = fridge.instantiate()
    with pytest.raises(eac.ParameterError, match="4x4 world pose"):
        inst.force("open", grasp=None)
    with pytest.raises(eac.ParameterError, match="4x4 world pose"):
        inst.follow("open", grasp=None, to=0.5)

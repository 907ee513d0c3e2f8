"""The runtime's fast paths agree with the plain numpy checks and evaluations they shortcut:
parameter packing, pose validation, ``grasps(n)`` through the reused-buffer small batch, and
``force`` without a linear solve. Same values, same errors."""

from __future__ import annotations

from pathlib import Path
from typing import Any

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

import grace_dsl as eac
from grace_dsl.runtime.concept import ParamSpec, suggest
from grace_dsl.runtime.errors import GraceError, ParameterError, UnknownNameError
from grace_dsl.runtime.inputs import MAX_COORDINATE, check_pose
from grace_dsl.runtime.instance import _pose

SOURCE = """
use primitives.{Cuboid}

/// A box with one sliding lid, for the runtime's fast paths.
concept Gadget {
    param size : vec3 length in [(100mm, 100mm, 50mm), (400mm, 300mm, 200mm)] = (200mm, 150mm, 80mm)
    param tilt : angle in [-30deg, 30deg] = 0deg
    param slats : int in [1, 6] = 2
    param mirrored : bool = false
    param side : choice{"left", "right"} = "left"
    param gain : scalar = 1.5
    require size.x > size.z "wider than tall"

    shape body = Cuboid(size: size)
    link lid {
        shape plate = Cuboid(size: (size.x, size.y, 10mm)) at trans(0, 0, size.z / 2 + 5mm)
    }
    joint slide : prismatic(base -> lid) axis (1, 0, 0) range [0, size.x / 2]
    joint turn : revolute(lid -> lid2) axis (0, 0, 1) at (size.x / 4, 0, 0) range [0, 90deg]
    link lid2 { shape cap = Cuboid(size: (20mm, 20mm, 20mm)) at trans(0, 0, size.z / 2 + 20mm) }

    /// Two free parameters: a Halton spread.
    grasp edge(u in [-size.x / 2, size.x / 2] = 0, a in [-tilt - 10deg, tilt + 10deg] = 0) =
        trans(u, 0, size.z / 2 + 10mm) * rotz(a) * roty(180deg) width 20mm
    /// One free parameter on the moving knob.
    grasp knob(h in [0mm, 10mm] = 0mm) = trans(0, h, size.z / 2 + 30mm) * roty(180deg) width 20mm
    /// No free parameter.
    grasp top = trans(0, 0, size.z / 2 + 10mm) * roty(180deg)

    action open = pull along slide using edge
    action twist = push along turn using knob
    action press = press toward (0, 0, -1) using top
}
"""


@pytest.fixture(scope="module")
def gadget(tmp_path_factory: pytest.TempPathFactory) -> eac.Concept:
    path = Path(tmp_path_factory.mktemp("fast")) / "gadget.eac"
    path.write_text(SOURCE)
    return eac.compile_paths([path])["Gadget"]


def slow_pack(specs: tuple[ParamSpec, ...], values: dict[str, Any], concept: str) -> np.ndarray:
    """The validating reference: every value through ``ParamSpec.encode``."""
    by_name = {s.name: s for s in specs}
    for name in values:
        if name not in by_name:
            raise UnknownNameError(f"{concept} has no parameter {name!r}" + suggest(name, by_name))
    p = np.empty(sum(s.size for s in specs))
    for s in specs:
        if s.name in values:
            p[s.offset : s.offset + s.size] = s.encode(values[s.name])
        else:
            p[s.offset : s.offset + s.size] = np.atleast_1d(np.asarray(s.default, dtype=float))
    return p


def outcome(fn: Any, *args: Any) -> Any:
    try:
        return fn(*args)
    except GraceError as err:
        return (type(err), str(err))


number = st.one_of(
    st.floats(allow_nan=True, allow_infinity=True),
    st.floats(-1.0, 1.0),
    st.integers(-3, 8),
    st.floats(-1.0, 1.0).map(np.float64),
    st.booleans(),
)
values = st.dictionaries(
    st.sampled_from(["size", "tilt", "slats", "mirrored", "side", "gain", "sise"]),
    st.one_of(
        number,
        st.tuples(number, number, number),
        st.tuples(number, number),
        st.lists(st.floats(0.05, 0.5), min_size=3, max_size=3).map(np.array),
        st.sampled_from(["left", "right", "up"]),
    ),
    max_size=4,
)


@settings(max_examples=300, deadline=None, derandomize=True)
@given(values=values)
def test_packing_matches_the_validating_path(gadget: eac.Concept, values: dict[str, Any]) -> None:
    want = outcome(slow_pack, gadget.params, values, gadget.name)
    got = outcome(lambda: gadget.pack(**values))
    if isinstance(want, np.ndarray):
        np.testing.assert_array_equal(got, want)
    else:
        assert got == want


def test_packing_accepts_bounds_within_the_tolerance(gadget: eac.Concept) -> None:
    hi = gadget.pack(tilt=np.radians(30) + 5e-13, size=(0.4 + 5e-13, 0.3, 0.2))
    assert hi[3] == np.radians(30) + 5e-13 and hi[0] == 0.4 + 5e-13
    with pytest.raises(ParameterError, match="tilt"):
        gadget.pack(tilt=np.radians(30) + 1e-9)


def numpy_pose_check(value: Any) -> Any:
    """The pose validation written with numpy alone (the reference for the plain-float path)."""
    m = np.asarray(value, dtype=float)
    if m.shape != (4, 4) or not np.all(np.isfinite(m)):
        return "not finite"
    r = m[:3, :3]
    if np.abs(r.T @ r - np.eye(3)).max() > 1e-6 or np.abs(m[3] - (0, 0, 0, 1)).max() > 1e-12:
        return "not rigid"
    if np.abs(m[:3, 3]).max() > MAX_COORDINATE:
        return "too far"
    return m


def random_rotation(rng: np.random.Generator) -> np.ndarray:
    q, _ = np.linalg.qr(rng.normal(size=(3, 3)))
    return q * np.sign(np.linalg.det(q))


@settings(max_examples=400, deadline=None, derandomize=True)
@given(
    seed=st.integers(0, 2**16),
    entry=st.tuples(st.integers(0, 3), st.integers(0, 3)),
    delta=st.sampled_from([0.0, 1e-13, 1e-9, 4e-7, 6e-7, 1e-6, 2e-6, 1e-3, np.nan, np.inf]),
    scale=st.sampled_from([1.0, 1e3, 1e300]),
)
def test_pose_checks_agree(seed: int, entry: tuple[int, int], delta: float, scale: float) -> None:
    rng = np.random.default_rng(seed)
    m = np.eye(4)
    m[:3, :3], m[:3, 3] = random_rotation(rng), rng.normal(size=3) * scale
    m[entry] += delta
    want = numpy_pose_check(m)
    try:
        got = check_pose(m)
    except ParameterError as err:
        assert isinstance(want, str), err
        assert ("finite" in str(err)) == (want == "not finite")
        assert ("within" in str(err)) == (want == "too far")
    else:
        assert not isinstance(want, str), (want, m)
        assert got is m  # a valid float64 array is checked as given, not copied
        owned = _pose(m)  # what an instance keeps: a copy
        assert owned is not m and np.array_equal(owned, m)


def test_pose_accepts_lists_and_rejects_shapes() -> None:
    np.testing.assert_array_equal(_pose(np.eye(4).tolist()), np.eye(4))
    with pytest.raises(ParameterError, match="4x4"):
        _pose(np.eye(3))
    with pytest.raises(ParameterError, match="rigid"):
        _pose(np.diag([2.0, 1.0, 1.0, 1.0]))


def instance(gadget: eac.Concept, seed: int) -> Any:
    rng = np.random.default_rng(seed)
    pose = np.eye(4)
    pose[:3, :3], pose[:3, 3] = random_rotation(rng), rng.normal(size=3)
    return gadget.instantiate(
        pose=pose,
        joints={"slide": float(rng.uniform(0, 0.05)), "turn": float(rng.uniform(0, 1.5))},
        tilt=float(rng.uniform(-0.5, 0.5)),
        size=(0.3, 0.2, 0.1),
    )


@pytest.mark.parametrize("seed", [0, 1, 2])
@pytest.mark.parametrize("grasp", ["knob", "top"])
@pytest.mark.parametrize("n", [1, 2, 16, 1500])  # 1500: past the small batch, the generic path
def test_grasps_are_the_single_grasps(gadget: eac.Concept, seed: int, grasp: str, n: int) -> None:
    inst = instance(gadget, seed)
    poses = inst.grasps(grasp, n=n)
    assert poses.shape == (n, 4, 4) and poses.flags.c_contiguous
    ranges = inst.grasp_range(grasp)
    for k in sorted({0, n // 2, n - 1}):
        free = {}
        if ranges:  # one free parameter: evenly spaced, both ends included
            ((name, (lo, hi)),) = ranges.items()
            free = {name: float(np.linspace(lo, hi, n)[k])}
        np.testing.assert_allclose(poses[k], inst.grasp(grasp, **free), rtol=0, atol=1e-12)


def test_two_free_parameters_spread_inside_their_box(gadget: eac.Concept) -> None:
    inst = instance(gadget, 3)
    poses = inst.grasps("edge", n=64)
    (ulo, uhi), (alo, ahi) = inst.grasp_range("edge").values()
    # back to the concept frame: u is the x of the position, a the yaw of the gripper
    local = np.linalg.inv(inst.pose) @ poses
    u = local[:, 0, 3]
    a = np.arctan2(-local[:, 1, 0], -local[:, 0, 0])  # rotz(a) * roty(180deg)
    assert np.all((u >= ulo - 1e-12) & (u <= uhi + 1e-12))
    assert np.all((a >= alo - 1e-9) & (a <= ahi + 1e-9))
    assert len(np.unique(np.round(u, 9))) == 64  # a Halton spread, no repeats
    for k in (0, 17, 63):
        np.testing.assert_allclose(poses[k], inst.grasp("edge", u=u[k], a=a[k]), atol=1e-12)


def test_small_batch_matches_the_generic_batch(gadget: eac.Concept) -> None:
    inst = instance(gadget, 4)
    fn = gadget.function("grasp", "edge")
    g = np.random.default_rng(0).uniform(-0.1, 0.1, size=(40, 2))
    small = fn.batch(inst.p, inst.q, g)
    generic = fn.batch(inst.p, inst.q, g, threads=2)  # threads: the generic path
    np.testing.assert_array_equal(small, generic)
    # the same buffers serve the next call: earlier results must not change
    again = fn.batch(inst.p * 1.0, inst.q, g[::-1].copy())
    np.testing.assert_array_equal(small, generic)
    np.testing.assert_array_equal(again, generic[::-1])
    # batched parameters and joints too, as (N, size) and (N, size, 1)
    ps = np.repeat(inst.p[None], 40, axis=0)
    qs = np.repeat(inst.q[None, :, None], 40, axis=0)
    np.testing.assert_array_equal(fn.batch(ps, qs, g), generic)


@pytest.mark.parametrize("action", ["open", "twist", "press"])
def test_force_matches_the_solve(gadget: eac.Concept, action: str) -> None:
    inst = instance(gadget, 5)
    rng = np.random.default_rng(7)
    for _ in range(5):
        g = np.eye(4)
        g[:3, :3], g[:3, 3] = random_rotation(rng), inst.pose[:3, 3] + rng.normal(size=3) * 0.1
        point = np.linalg.solve(inst.pose, g[:, 3])[:3]
        concept_frame = np.eye(4)[:3]  # the kernel at M = [I | 0]: the force in the concept
        f_local = np.asarray(
            gadget.function("force", action)(inst.p, inst.q, concept_frame, point)
        ).reshape(3)
        want = inst.pose[:3, :3] @ f_local
        np.testing.assert_allclose(inst.force(action, grasp=g), want, atol=1e-12)
        assert np.linalg.norm(want) == pytest.approx(1.0)


def test_bad_values_still_raise(gadget: eac.Concept) -> None:
    with pytest.raises(ParameterError, match="outside its range"):
        gadget.instantiate(joints={"slide": 1.0})
    with pytest.raises(ParameterError, match="outside its range"):
        gadget.instantiate(joints={"slide": float("nan")})
    with pytest.raises(UnknownNameError, match="did you mean 'slide'"):
        gadget.instantiate(joints={"slid": 0.0})
    with pytest.raises(eac.RequirementError, match="wider than tall"):
        gadget.instantiate(size=(0.1, 0.1, 0.15))
    inst = gadget.instantiate()
    with pytest.raises(ParameterError, match="rigid"):
        inst.force("open", grasp=np.diag([1.0, 1.0, 2.0, 1.0]))
    with pytest.raises(ParameterError, match="at least 1"):
        inst.grasps("edge", n=0)

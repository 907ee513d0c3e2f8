"""The scene description agrees with the runtime: meshes per link, grasp frames, forces, twists,
and joint axes that move the child link exactly as the joint does."""

from __future__ import annotations

import math

import numpy as np
import pytest
import trimesh
from hypothesis import given, settings
from hypothesis import strategies as st

import grace_dsl as eac
from grace_dsl.compiler.build import front_end
from grace_dsl.compiler.resolve import stdlib_dir
from grace_dsl.geometry import PRIMITIVES, default_params, primitive_mesh
from grace_dsl.render import describe, primitive_scene, style
from tests.render.conftest import random_pose


def _instance(toy: eac.Library, seed: int) -> eac.Instance:
    rng = np.random.default_rng(seed)
    joints = {"hinge": rng.uniform(0, 1.7), "slide": rng.uniform(0, 0.2), "pull.twist": 1.0}
    return toy["ToyBox"].instantiate(pose=random_pose(rng), joints=joints)


def _rotation(axis: np.ndarray, angle: float) -> np.ndarray:
    """Rodrigues' formula: an independent rotation about a unit axis."""
    k = np.array([[0, -axis[2], axis[1]], [axis[2], 0, -axis[0]], [-axis[1], axis[0], 0]])
    return np.eye(3) + math.sin(angle) * k + (1 - math.cos(angle)) * k @ k


@settings(max_examples=8, deadline=None)
@given(seed=st.integers(0, 2**31 - 1))
def test_parts_are_the_link_meshes_in_link_colours(toy, seed) -> None:
    inst = _instance(toy, seed)
    scene = describe(inst)
    links = list(inst.concept.links)
    assert [p.link for p in scene.parts] == [
        link for link in links if len(inst.link_mesh(link, resolution=48).faces)
    ]
    for part in scene.parts:
        mesh = inst.link_mesh(part.link, resolution=48)
        np.testing.assert_allclose(part.vertices, mesh.vertices, atol=1e-12)
        np.testing.assert_array_equal(part.faces, mesh.faces)
        assert part.color == style.link_color(links.index(part.link))


@settings(max_examples=8, deadline=None)
@given(seed=st.integers(0, 2**31 - 1), n=st.integers(1, 5))
def test_frames_are_the_grasps(toy, seed, n) -> None:
    inst = _instance(toy, seed)
    scene = describe(inst, grasps=n)
    for name, entry in inst.concept.grasps.items():
        poses = [f.pose for f in scene.frames if f.grasp == name]
        expected = inst.grasps(name, n if entry["free"] else 1)
        np.testing.assert_allclose(np.array(poses), expected, atol=1e-12)
    assert describe(inst, grasps=0).frames == ()
    with pytest.raises(eac.ParameterError):
        describe(inst, grasps=-1)


@settings(max_examples=8, deadline=None)
@given(seed=st.integers(0, 2**31 - 1))
def test_forces_at_each_used_grasp_and_twists_on_an_axis(toy, seed) -> None:
    inst = _instance(toy, seed)
    scene = describe(inst)
    pairs = [(f.action, f.grasp) for f in scene.forces]
    expected = [
        (a, g) for a, e in inst.concept.actions.items() for g in e["using"] or inst.concept.grasps
    ]
    assert pairs == expected
    for f in scene.forces:
        grasp = inst.grasp(f.grasp)
        np.testing.assert_allclose(f.origin, grasp[:3, 3], atol=1e-12)
        if f.twist:  # the knob's top grasp sits on its axis
            with pytest.raises(eac.ParameterError):
                inst.force(f.action, grasp)
            np.testing.assert_allclose(f.direction, inst.twist(f.action), atol=1e-12)
        else:
            np.testing.assert_allclose(f.direction, inst.force(f.action, grasp), atol=1e-12)
        assert abs(np.linalg.norm(f.direction) - 1) < 1e-9
    assert [f.twist for f in scene.forces].count(True) == 1


@settings(max_examples=8, deadline=None)
@given(seed=st.integers(0, 2**31 - 1), dq=st.floats(-0.3, 0.3))
def test_joint_axes_move_the_child_as_the_joint_does(toy, seed, dq) -> None:
    """Moving joint j by dq moves its child link by a rotation of dq about the drawn axis through
    the drawn origin (revolute, continuous) or a shift of dq along it (prismatic)."""
    inst = _instance(toy, seed)
    scene = describe(inst)
    concept = inst.concept
    assert [j.joint for j in scene.joints] == list(concept.moving_joints)
    for i, j in enumerate(scene.joints):
        q = inst.q.copy()
        lo, hi = inst.joint_limits()[j.joint]
        q[i] = float(np.clip(q[i] + dq, lo, hi)) if np.isfinite(lo) else q[i] + dq
        step = q[i] - inst.q[i]
        moved = concept.instantiate(
            pose=inst.pose, joints=dict(zip(concept.moving_joints, q)), **inst.params
        )
        child = concept.joints[j.joint]["child"]
        before, after = inst.link_pose(child), moved.link_pose(child)
        motion = np.eye(4)
        axis, origin = np.array(j.direction), np.array(j.origin)
        if j.kind == "prismatic":
            motion[:3, 3] = step * axis
        else:
            motion[:3, :3] = _rotation(axis, step)
            motion[:3, 3] = origin - motion[:3, :3] @ origin
        np.testing.assert_allclose(after, motion @ before, atol=1e-9)


def test_joint_axes_stick_out_of_what_they_move(toy) -> None:
    inst = _instance(toy, 3)
    scene = describe(inst)
    segs = {s.label: s for s in scene.segments() if s.kind == "joint"}
    for j in scene.joints:
        child = inst.concept.joints[j.joint]["child"]
        pts = np.concatenate([p.vertices for p in scene.parts if p.link.startswith(child)])
        along = (pts - np.array(j.origin)) @ np.array(j.direction)
        seg = segs[j.joint]
        s0 = (np.array(seg.start) - j.origin) @ np.array(j.direction)
        s1 = (np.array(seg.end) - j.origin) @ np.array(j.direction)
        if j.kind == "prismatic":  # from the front of the drawer, outwards
            assert s0 == pytest.approx(along.max()) and s1 > s0
        else:
            assert s0 < along.min() and s1 > along.max()
        assert seg.head and seg.color == style.JOINT


def test_segments_colour_frames_and_put_heads_on_arrows(toy) -> None:
    scene = describe(_instance(toy, 5))
    axes = [s for s in scene.segments() if s.kind == "axis"]
    assert len(axes) == 3 * len(scene.frames)
    for frame, xyz in zip(scene.frames, zip(axes[0::3], axes[1::3], axes[2::3])):
        for k, seg in enumerate(xyz):
            assert seg.color == style.FRAME_AXES[k] and not seg.head
            d = np.subtract(seg.end, seg.start)
            np.testing.assert_allclose(d / np.linalg.norm(d), frame.pose[:3, k], atol=1e-9)
            assert np.linalg.norm(d) == pytest.approx(frame.length)
    arrows = [s for s in scene.segments() if s.kind in ("force", "twist")]
    assert len(arrows) == len(scene.forces) and all(s.head for s in arrows)
    assert {s.color for s in arrows} == {style.FORCE, style.TWIST}
    lo, hi = scene.bounds()
    for s in scene.segments():
        assert np.all(np.array([s.start, s.end]) >= lo - 1e-12)
        assert np.all(np.array([s.start, s.end]) <= hi + 1e-12)


@pytest.mark.parametrize("name", sorted(PRIMITIVES))
def test_primitive_scene_of_every_registry_primitive(name: str) -> None:
    scene = primitive_scene(name)
    (part,) = scene.parts
    mesh = primitive_mesh(name, default_params(name), resolution=48)
    solid = trimesh.Trimesh(part.vertices, part.faces)
    assert solid.volume == pytest.approx(mesh.volume, rel=1e-9)
    assert part.opacity < 1  # its own frame shows through
    (frame,) = scene.frames
    np.testing.assert_array_equal(frame.pose, np.eye(4))


def _library_concepts() -> list[str]:
    prog, _, _ = front_end([stdlib_dir()])
    return sorted(n for n, e in prog.concepts.items() if e.decl.kind != "primitive")


@pytest.mark.parametrize("name", _library_concepts())
def test_every_library_concept_has_a_scene(stdlib, name: str) -> None:
    inst = stdlib[name].instantiate()
    scene = describe(inst)
    assert scene.parts and scene.size > 0
    families = {f.grasp for f in scene.frames}
    assert families == set(inst.grasp_names)  # a repeated part's copies the instance has
    for f in scene.forces:
        assert abs(np.linalg.norm(f.direction) - 1) < 1e-9
    assert len(scene.joints) == len([j for j in inst.concept.moving_joints if j in inst.joints])

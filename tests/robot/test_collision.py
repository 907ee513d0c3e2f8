"""Collision scenes: robot against instance and itself, checked against the raw URDF meshes."""

from __future__ import annotations

import numpy as np
import pinocchio as pin
import pytest

import grace_dsl as eac
from grace_dsl.robot.collision import collision_scene
from grace_dsl.robot.model import Robot


@pytest.fixture(scope="module")
def drawer(lib: eac.Library) -> eac.Concept:
    return lib["CabinetDrawer"]


def _at(xyz: tuple[float, float, float]) -> np.ndarray:
    m = np.eye(4)
    m[:3, 3] = xyz
    return m


def test_hulls_are_conservative_against_the_meshes(panda: Robot) -> None:
    """Where the convex hulls see no self-collision, the URDF's own meshes see none either."""
    scene = collision_scene(panda)
    mesh_geom = panda.collision.copy()
    mesh_geom.removeAllCollisionPairs()
    for pair in scene.geometry.collisionPairs:
        mesh_geom.addCollisionPair(pin.CollisionPair(pair.first, pair.second))
    mesh_data = mesh_geom.createData()
    rng = np.random.default_rng(0)
    hull_hits = mesh_hits = 0
    for _ in range(150):
        q = panda.random_q(rng)
        hull = scene.collides(q)
        mesh = pin.computeCollisions(panda.model, panda.data(), mesh_geom, mesh_data, q, True)
        assert hull or not mesh, q  # a mesh contact inside hulls that do not touch is impossible
        hull_hits += hull
        mesh_hits += mesh
    assert hull_hits >= mesh_hits > 0  # random arms do fold into themselves sometimes


def test_home_is_free_and_an_object_in_the_hand_collides(panda: Robot, drawer) -> None:  # type: ignore[no-untyped-def]
    assert not collision_scene(panda).collides(panda.home)
    far = collision_scene(panda, drawer.instantiate(pose=_at((0.0, 2.0, 0.3))))
    assert not far.collides(panda.home) and far.object_distance(panda.home) > 1.0
    tcp = panda.fk(panda.home)[:3, 3]
    inside = collision_scene(panda, drawer.instantiate(pose=_at(tuple(tcp))))
    assert inside.collides(panda.home)
    names = {c.first for c in inside.contacts(panda.home)} | {
        c.second for c in inside.contacts(panda.home)
    }
    assert any(n.startswith("object/") for n in names)
    assert inside.object_distance(panda.home) < 0


def test_distance_shrinks_as_the_object_approaches(panda: Robot, drawer) -> None:  # type: ignore[no-untyped-def]
    scenes = [
        collision_scene(panda, drawer.instantiate(pose=_at((x, 0.0, 0.2)))) for x in (1.4, 1.2, 1.0)
    ]
    gaps = [scene.object_distance(panda.home) for scene in scenes]
    assert gaps[0] > gaps[1] > gaps[2] > 0
    assert gaps[0] - gaps[2] <= 0.4 + 1e-9  # a distance changes no faster than the object moves


def test_ignored_fingers_may_touch(panda: Robot, drawer) -> None:  # type: ignore[no-untyped-def]
    tcp = panda.fk(panda.home)
    pose = _at((tcp[0, 3], tcp[1, 3], tcp[2, 3] - 0.08))  # the drawer's top face near the tips
    inst = drawer.instantiate(pose=pose)
    strict = collision_scene(panda, inst)
    touching = {c.first for c in strict.contacts(panda.home)}
    lenient = collision_scene(panda, inst, ignore=("panda_leftfinger", "panda_rightfinger"))
    rest = {c.first for c in lenient.contacts(panda.home)}
    assert not any("finger" in n for n in rest)
    assert rest <= touching


def test_bad_configuration_is_a_typed_error(panda: Robot) -> None:
    with pytest.raises(eac.ParameterError):
        collision_scene(panda).collides([0.0, 1.0])


def test_placing_the_object_equals_building_it_there(panda: Robot, drawer) -> None:  # type: ignore[no-untyped-def]
    inst = drawer.instantiate(pose=_at((0.55, 0.0, 0.3)))
    moved = collision_scene(panda, inst)
    gaps = [moved.object_distance(panda.home)]
    for slide in (0.1, 0.3):
        opened = inst.with_joints(slide=slide)
        moved.place(opened)
        fresh = collision_scene(panda, opened)
        gaps.append(moved.object_distance(panda.home))
        assert gaps[-1] == pytest.approx(fresh.object_distance(panda.home), abs=1e-6)  # float32
    assert len(set(np.round(gaps, 4))) == 3  # the drawer did move


def test_held_link_may_be_pressed_only_within_the_allowance(panda: Robot, lib) -> None:  # type: ignore[no-untyped-def]
    from grace_dsl.robot.choose import choose_grasp
    from tests.robot.test_grasp_ik import facing

    door = lib["SunkenDoor"]
    choice = choose_grasp(panda, door.instantiate(pose=facing(0.7, 0.0, 0.45)), "open")
    fingers = [("panda_leftfinger", "leaf"), ("panda_rightfinger", "leaf")]
    approach = choice.ik.grasp_pose[:3, 2]
    verdicts = {}
    for push in (0.0, 0.02):  # the door moved toward the hand: the fingertips sink into it
        pose = facing(0.7, 0.0, 0.45)
        pose[:3, 3] -= push * approach
        inst = door.instantiate(pose=pose)
        for allowance in (0.005, 0.03):
            scene = collision_scene(panda, inst, touching=fingers, allowance=allowance)
            verdicts[push, allowance] = scene.collides(choice.ik.q)
            if verdicts[push, allowance]:
                hits = scene.contacts(choice.ik.q)
                assert all("finger" in h.first and -push < h.distance < -allowance for h in hits)
        assert collision_scene(panda, inst).collides(choice.ik.q) == (push > 0)
    assert verdicts == {
        (0.0, 0.005): False,
        (0.0, 0.03): False,
        (0.02, 0.005): True,
        (0.02, 0.03): False,
    }

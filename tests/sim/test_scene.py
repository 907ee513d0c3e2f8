"""Scenes: the object stands z-up on the floor, the seeded camera follows the protocol, depth
back-projects onto the object's surface, segmentation names its links, and the hook for extra
bodies (the hand) composes with it."""

from __future__ import annotations

import numpy as np
import pytest

import grace_dsl as eac
from grace_dsl.runtime.shapes import instance_sdf

mujoco = pytest.importorskip("mujoco")

from grace_dsl.sim.camera import Camera, CameraError  # noqa: E402
from grace_dsl.sim.scene import Scene, SceneError  # noqa: E402

SMALL = {"width": 160, "height": 120}


@pytest.fixture(scope="module")
def drawer() -> eac.Instance:
    lib = eac.load_library()
    inst = lib["CabinetDrawer"].instantiate()
    return inst.with_joints({inst.concept.moving_joints[0]: 0.15})


def test_random_cameras_follow_the_protocol_and_the_seed() -> None:
    cams = [Camera.random(np.random.default_rng(s)) for s in range(200)]
    az = np.array([c.azimuth for c in cams])
    el = np.array([c.elevation for c in cams])
    assert az.min() >= 0 and az.max() < 360 and np.ptp(az) > 300
    assert el.min() >= 30 and el.max() <= 60 and np.ptp(el) > 25
    assert Camera.random(np.random.default_rng(7)) == Camera.random(np.random.default_rng(7))
    with pytest.raises(CameraError):
        Camera(distance=-1.0)


def test_depth_lies_on_the_object_and_segments_name_its_links(drawer) -> None:
    scene = Scene.from_instances([drawer], camera=Camera.random(np.random.default_rng(3), **SMALL))
    model, data = scene.compile()
    frame = scene.render(model, data)
    assert frame.rgb.shape == (120, 160, 3) and frame.depth.shape == (120, 160)
    cloud = scene.point_cloud(frame)
    on_object = cloud.bodies > 0  # 0: the world (the floor)
    assert on_object.sum() > 500
    world = cloud.world_points[on_object]
    placed = scene.instances[0]
    assert np.abs(instance_sdf(placed, world)).max() < 3e-3
    floor = cloud.world_points[cloud.bodies == 0]
    assert len(floor) == 0 or np.abs(floor[:, 2]).max() < 3e-3
    links = {scene.link_of(model, b) for b in np.unique(cloud.bodies[on_object])}
    assert links <= {(0, name) for name in drawer.links}
    assert (0, "drawer") in links and (0, "base") in links
    # the camera frame is the world frame seen from the camera: in front of it along -z
    assert np.all(cloud.camera_points[:, 2] < 0)


def test_the_object_stands_z_up_at_its_joint_values(drawer) -> None:
    scene = Scene.from_instances([drawer])
    model, data = scene.compile()
    joint = model.joint(scene.name(0, "slide"))
    assert data.qpos[model.jnt_qposadr[joint.id]] == pytest.approx(0.15)
    low = min(
        np.asarray(m.vertices)[:, 2].min()
        for m in eac.runtime.shapes.instance_meshes(scene.instances[0])
    )
    assert 0 < low < 0.01  # resting just above the floor


@pytest.mark.slow
def test_same_seed_same_image(drawer) -> None:
    def image(seed: int) -> np.ndarray:
        cam = Camera.random(np.random.default_rng(seed), **SMALL)
        scene = Scene.from_instances([drawer], camera=cam)
        return scene.render(*scene.compile()).rgb

    first = image(11)
    assert np.array_equal(first, image(11))
    assert not np.array_equal(first, image(12))


def test_extra_bodies_attach_and_two_instances_get_prefixes(drawer) -> None:
    hand = mujoco.MjSpec()
    body = hand.worldbody.add_body(name="hand", pos=[0, -1, 1], mocap=True)
    body.add_geom(type=mujoco.mjtGeom.mjGEOM_BOX, size=[0.02, 0.02, 0.02])
    scene = Scene.from_instances([drawer, drawer], camera=Camera(**SMALL))
    model, data = scene.compile(extra=[(hand, "hand/")])
    assert model.nmocap == 1 and model.body("hand/hand").id > 0
    assert model.joint("obj1/slide").id >= 0
    assert "hand/hand" in scene.mjcf(extra=[(hand, "hand/")])
    assert scene.link_of(model, model.body("obj1/drawer").id) == (1, "drawer")
    with pytest.raises(SceneError):
        Scene.from_instances([])

"""Estimated mode's looks: a label per point from the renderer's segmentation (shape, part,
link) and where the agent looks next (a pure, deterministic choice)."""

from __future__ import annotations

import math

import numpy as np
import pytest

import grace_dsl as eac
from grace_dsl.agent.estimated import (
    LOW_ELEVATION,
    PART,
    SAME_VIEW,
    Sight,
    View,
    camera_for,
    frame_of,
    labelled_cloud,
    next_view,
    object_cloud,
    object_shot,
    render_from,
)
from grace_dsl.perception.camera import back_project
from grace_dsl.sim.scene import Scene


@pytest.fixture(scope="module")
def drawer_shot(lib: eac.Library):  # type: ignore[no-untyped-def]
    """A CabinetDrawer standing with its front toward world +x, seen from the front."""
    scene = Scene.from_instances([lib["CabinetDrawer"].instantiate()], yaw=[math.pi / 2])
    model, data = scene.compile()
    centre, radius = frame_of(scene.instances[0])
    frame, geoms = render_from(scene, model, data, camera_for(View(15, 40), centre, radius))
    return frame, object_shot(frame, scene, model, 0, geoms)


def test_the_handles_points_carry_the_handles_label(drawer_shot) -> None:  # type: ignore[no-untyped-def]
    frame, shot = drawer_shot
    cloud = labelled_cloud(shot, frame.rgb, "CabinetDrawer", seed=0, noise=0.0)
    on_handle = np.zeros(shot.depth.shape, bool)
    for k, name in enumerate(shot.shapes):
        if name.split(".")[0] == PART:
            on_handle |= shot.shape_labels == k
    # every pixel of the object is one point, the handle's pixels are the handle's points
    assert len(cloud) == int(np.count_nonzero((shot.labels >= 0) & (shot.depth > 0)))
    assert cloud.count(PART) == int(np.count_nonzero(on_handle & (shot.depth > 0))) > 50
    assert np.allclose(cloud.points[cloud.on(PART)],
                       back_project(shot.depth, shot.intrinsics, on_handle))  # fmt: skip
    # each point is labelled with its shape (the handle's bar and posts apart), owned by its link
    assert {str(x) for x in cloud.labels[cloud.on(PART)]} == {
        "handle.bar", "handle.left_post", "handle.right_post"}  # fmt: skip
    assert set(cloud.labels) <= set(shot.shapes)
    assert cloud.owners is not None and set(cloud.owners) == {"base", "drawer"}
    assert set(cloud.owners[cloud.on(PART)]) == {"drawer"}  # the handle is on the drawer
    # the part's cloud that object_cloud gives is the same pixels
    points, handle = object_cloud(shot, frame.rgb, "CabinetDrawer", seed=0, noise=0.0, part=PART)
    assert handle is not None and len(handle) == cloud.count(PART) and len(points) == len(cloud)


def test_the_noise_is_seeded_and_leaves_the_labels(drawer_shot) -> None:  # type: ignore[no-untyped-def]
    frame, shot = drawer_shot
    a = labelled_cloud(shot, frame.rgb, "CabinetDrawer", seed=3)
    b = labelled_cloud(shot, frame.rgb, "CabinetDrawer", seed=3)
    clean = labelled_cloud(shot, frame.rgb, "CabinetDrawer", seed=3, noise=0.0)
    assert np.array_equal(a.points, b.points) and np.array_equal(a.labels, clean.labels)
    assert 0.001 < float(np.std(a.points[:, 2] - clean.points[:, 2])) < 0.003  # sigma 2 mm


def test_the_next_view_faces_where_the_handle_was_seen() -> None:
    first = View(170.0, 40.0)
    centre = (0.0, 0.0, 0.5)
    # from the back nothing of the front: the opposite side
    back = Sight(first, centre)
    assert next_view(first, [back]) == View(350.0, 40.0)
    # a few handle pixels seen toward +y of the centre: look from +y (azimuth 90)
    side = Sight(View(120.0, 40.0), centre, handle_at=(0.05, 0.4, 0.6))
    got = next_view(first, [side])
    assert abs(got.azimuth - math.degrees(math.atan2(0.4, 0.05))) < 1e-6
    assert got.elevation == 40.0
    # no handle, but an estimated front toward -x: from azimuth 180
    fitted = Sight(View(100.0, 40.0), centre, front=(-1.0, 0.0, 0.0))
    assert next_view(first, [fitted]).azimuth == 180.0
    # a front facing a camera that saw none of the handle is flipped: the other way
    flipped = Sight(View(150.0, 40.0), centre, front=(-1.0, 0.2, 0.0), handle=0)
    assert next_view(first, [flipped]).azimuth == pytest.approx(
        (math.degrees(math.atan2(0.2, -1.0)) + 180) % 360
    )
    # the newest sight decides; a view already taken is not repeated
    near = Sight(View(10.0, 40.0), centre, handle_at=(1.0, 0.0, 0.5))
    got = next_view(first, [back, near])
    assert all(abs((got.azimuth - t + 180) % 360 - 180) >= SAME_VIEW for t in (170.0, 10.0))
    assert got.azimuth == 45.0  # turned 45 degrees from the handle's direction (0)
    assert next_view(first, [back, near]) == got  # a function of the sights


def test_a_hidden_handle_is_looked_for_from_lower() -> None:
    """An oven's open door hides its handle from above: with none of it seen yet, the next look
    goes to LOW_ELEVATION, toward the moved link's pixels (the door)."""
    first = View(60.0, 45.0)
    door = Sight(first, (0.0, 0.0, 0.4), handle_at=(0.6, 0.0, 0.2), handle=0)
    assert next_view(first, [door]) == View(0.0, LOW_ELEVATION)
    seen = Sight(first, (0.0, 0.0, 0.4), handle_at=(0.6, 0.0, 0.2), handle=30)
    assert next_view(first, [seen]) == View(0.0, 45.0)


@pytest.mark.slow  # renders, fits and runs the hand (about 10 s)
def test_a_drawer_seen_from_the_front_is_opened_on_its_estimate() -> None:
    """CabinetDrawer, open, seed 6: the protocol's camera sees the front (azimuth 49 deg, the
    front faces +x). With the handle's points labelled the fit places the handle and the hand
    opens the drawer past half its travel, on the estimate alone (before the labels: a slip)."""
    from grace_dsl.agent.estimated_episode import run_estimated_episode
    from grace_dsl.sim.records import EpisodeConfig

    record = run_estimated_episode(EpisodeConfig("CabinetDrawer", "open", mode="estimated"), 6)
    (only,) = record.estimate["looks"]  # the first look was accepted
    assert only["handle_points"] > 100 and only["confidence"] >= 0.5
    assert not record.estimate["refused"] and record.estimate["pose_error_mm"] < 25
    assert record.strict, (record.reason, record.detail)

"""The reverse geometry check of ``rank``: the part's surface inside the hand's swept boxes, which
catches a plate thinner than the spacing of the samples on the boxes' faces."""

from __future__ import annotations

import numpy as np
import pytest

import grace_dsl as eac
from grace_dsl.runtime.contact import Boxes, Scene, swept_volumes
from grace_dsl.runtime.gripper import FingerBox, Gripper


def facing_robot() -> np.ndarray:
    """The part 1 m in front of the robot, its front (+z) facing back at it, +y up."""
    m = np.eye(4)
    m[:3, :3] = np.column_stack([[0, -1, 0], [0, 0, 1], [-1, 0, 0]])
    m[:3, 3] = (1.0, 0.0, 0.8)
    return m


@pytest.mark.slow
def test_topdown_push_on_a_dimmer_finds_the_wall_plate_in_the_palm(lib: eac.Library) -> None:
    """The top-down hand pushing a dimmer's slider down with its fingertip puts its 120 mm palm
    across the 6 mm wall plate, 3 mm into it: between two of the palm's face samples (10 mm
    apart), so only the reverse check sees it. Without it this option was called feasible."""
    inst = lib["SlideDimmer"].instantiate(pose=facing_robot())
    options = {o.grasp: o for o in inst.rank("dim", Gripper.load("topdown"))}
    push = options["push_down"]
    assert not push.feasible
    assert "by tip: the palm enters the part" in push.reasons[0]
    # the Panda, whose fingers stand clear of the plate, still pushes it
    assert any(o.feasible for o in inst.rank("dim", Gripper.panda()))


def test_inside_measures_how_deep_a_thin_plate_reaches_into_a_box(lib: eac.Library) -> None:
    inst = lib["SlideDimmer"].instantiate()
    scene = Scene.of(inst)
    lo, hi = (np.asarray(b) for b in inst.mesh(resolution=16).bounds)
    # a flat box (10 mm thick along y) over the part's top, 3 mm down into it, far wider than
    # the part along x and z: the part's top faces lie inside it
    box = np.eye(4)
    box[:3, 3] = ((lo[0] + hi[0]) / 2, hi[1] + 0.005 - 0.003, (lo[2] + hi[2]) / 2)
    half = np.array([0.3, 0.005, 0.3])
    depth, part = scene.inside(Boxes(box[None], half[None], ("palm",)), np.eye(4))
    assert part == "palm"
    # beyond the 2 mm a box may touch, and never more than the box's 3 mm reach into the part
    # (the depth is measured at probes along the inward normal: a lower bound, never more)
    assert 0.002 < depth <= 0.003 + 1e-9
    # lifted 5 mm clear of the part: nothing inside
    box[1, 3] += 0.008
    assert scene.inside(Boxes(box[None], half[None], ("palm",)), np.eye(4)) == (0.0, "")


def test_swept_volumes_cover_the_sweep() -> None:
    pose = np.eye(4)
    pose[:3, 3] = (0.0, 0.01, -0.02)
    box = FingerBox(pose, (0.01, 0.02, 0.03), "b", "palm")
    [(p, half, label)] = swept_volumes(box, np.array([0.0, 0.0, -0.08]))  # along an axis
    assert label == "palm"
    assert np.allclose(half, (0.01, 0.02, 0.07))
    assert np.allclose(p[:3, 3], (0.0, 0.01, -0.06))
    copies = swept_volumes(box, np.array([0.05, 0.0, -0.05]))  # oblique: copies along it
    centres = np.array([c[0][:3, 3] for c in copies])
    assert np.allclose(centres[0], pose[:3, 3]) and np.allclose(centres[-1], (0.05, 0.01, -0.07))
    gaps = np.linalg.norm(np.diff(centres, axis=0), axis=1)
    assert gaps.max() <= 0.01 + 1e-12  # at most the smallest half extent apart

"""Symmetric grasps (the paper's minimal-rotation rule) and turning actions."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from scipy.spatial.transform import Rotation

import grace_dsl as eac
from grace_dsl.runtime.symmetry import HAND_HOME, minimal_spin
from tests.conftest import write

CAP = """use primitives.{Cylinder}

/// A screw cap turned about its own axis z.
concept Cap {
    param radius : length in [10mm, 40mm] = 15mm
    param height : length in [5mm, 30mm] = 12mm
    link cap {
        shape body = Cylinder(radius: radius, height: height)
        /// Grip across the diameter from the front; any spin about the approach works.
        grasp across = trans(0, 0, height / 2 - 4mm) * roty(180deg) width 2 * radius symmetric
        /// Hook the rim from the side at angle a.
        grasp rim(a in [0, 90deg]) = rotz(a) * trans(radius, 0, 0) by hook symmetric about (1, 0, 0)
    }
    joint spin : continuous(base -> cap) axis (0, 0, 1)
    /// Unscrew: counter-clockwise seen from the front.
    action unscrew = turn along spin using across
}
"""

rotations = st.tuples(*[st.floats(-np.pi, np.pi)] * 3).map(
    lambda e: Rotation.from_euler("xyz", e).as_matrix()
)


@pytest.fixture(scope="module")
def cap(tmp_path_factory: pytest.TempPathFactory) -> eac.Concept:
    return eac.compile_paths([write(tmp_path_factory.mktemp("cap"), "cap.eac", CAP)])["Cap"]


def pose_of(rot: np.ndarray, t: tuple[float, float, float] = (0.4, -0.1, 0.8)) -> np.ndarray:
    m = np.eye(4)
    m[:3, :3], m[:3, 3] = rot, t
    return m


def test_the_manifest_states_mode_symmetry_and_demands(cap: eac.Concept) -> None:
    across, rim = cap.grasps["across"], cap.grasps["rim"]
    assert (across["mode"], across["symmetric"], across["demands"]) == (
        "pinch",
        True,
        {"closes": True, "orientation": "approach"},
    )
    assert (rim["mode"], rim["demands"]) == ("hook", {"closes": False, "orientation": "full"})


@pytest.mark.slow
@settings(max_examples=30, deadline=None)
@given(r0=rotations, ref=rotations, axis=st.tuples(*[st.floats(-1, 1)] * 3))
def test_minimal_spin_beats_every_other_spin(r0: np.ndarray, ref: np.ndarray, axis: tuple) -> None:
    a = np.asarray(axis)
    if np.linalg.norm(a) < 1e-3:
        return
    a = a / np.linalg.norm(a)
    phi = float(minimal_spin(r0, a, ref))
    grid = np.linspace(-np.pi, np.pi, 3601)
    scores = [np.trace(ref.T @ r0 @ Rotation.from_rotvec(p * a).as_matrix()) for p in grid]
    best = np.trace(ref.T @ r0 @ Rotation.from_rotvec(phi * a).as_matrix())
    assert best >= max(scores) - 1e-6


@settings(max_examples=20, deadline=None)
@given(m=rotations, spin=st.floats(-np.pi, np.pi), ref=rotations)
def test_the_grasp_does_not_depend_on_the_parts_unobservable_spin(
    cap: eac.Concept, m: np.ndarray, spin: float, ref: np.ndarray
) -> None:
    """A cap's pose from perception has an arbitrary spin about its axis; the grasp must not."""
    spun = m @ Rotation.from_rotvec([0, 0, spin]).as_matrix()
    a = cap.instantiate(pose=pose_of(m)).grasp("across", reference=ref)
    b = cap.instantiate(pose=pose_of(spun)).grasp("across", reference=ref)
    np.testing.assert_allclose(a, b, atol=1e-9)


def test_spinning_keeps_the_grasp_point_and_approach(cap: eac.Concept) -> None:
    inst = cap.instantiate(pose=pose_of(Rotation.from_euler("xyz", [0.3, -0.5, 1.1]).as_matrix()))
    raw = inst.pose @ cap.function("grasp", "across")(inst.p, inst.q, np.zeros(0))
    g = inst.grasp("across")
    np.testing.assert_allclose(g[:3, 3], raw[:3, 3], atol=1e-12)
    np.testing.assert_allclose(g[:3, 2], raw[:3, 2], atol=1e-12)
    assert np.trace(HAND_HOME.T @ g[:3, :3]) >= np.trace(HAND_HOME.T @ raw[:3, :3]) - 1e-12
    np.testing.assert_allclose(inst.grasps("across", 3), [g] * 3, atol=1e-12)


def test_a_batch_of_symmetric_grasps_matches_single_calls(cap: eac.Concept) -> None:
    inst = cap.instantiate(pose=pose_of(Rotation.from_euler("xyz", [1.0, 0.2, -0.7]).as_matrix()))
    batch = inst.grasps("rim", 5)
    for i, a in enumerate(np.linspace(0, np.pi / 2, 5)):
        np.testing.assert_allclose(batch[i], inst.grasp("rim", a=a), atol=1e-12)


def test_a_bad_reference_is_a_parameter_error(cap: eac.Concept) -> None:
    with pytest.raises(eac.ParameterError, match="reference must be a rotation"):
        cap.instantiate().grasp("across", reference=np.diag([1.0, 1.0, -1.0]))


def test_twist_is_the_joint_axis_and_follow_turns_about_it(cap: eac.Concept) -> None:
    m = pose_of(Rotation.from_euler("xyz", [0.4, 0.9, -0.2]).as_matrix())
    inst = cap.instantiate(pose=m)
    axis = inst.twist("unscrew")
    np.testing.assert_allclose(axis, m[:3, 2], atol=1e-12)
    g = inst.grasp("across")
    path = inst.follow("unscrew", grasp=g, to=0.5, steps=5)
    turn = Rotation.from_matrix(path[-1][:3, :3] @ path[0][:3, :3].T).as_rotvec()
    np.testing.assert_allclose(turn, 0.5 * axis, atol=1e-9)
    with pytest.raises(eac.ParameterError, match="twist"):
        inst.force("unscrew", grasp=g)  # on the axis: no linear force turns it


def test_twist_needs_a_turning_joint(tmp_path: Path) -> None:
    src = write(
        tmp_path,
        "d.eac",
        "use primitives.{Cuboid}\nconcept D {\n link box { shape b = Cuboid() }\n"
        " joint slide : prismatic(base -> box) axis (0, 0, 1) range [0, 300mm]\n"
        " action pull_out = pull along slide\n}\n",
    )
    inst = eac.compile_paths([src])["D"].instantiate()
    with pytest.raises(eac.ParameterError, match="revolute or continuous"):
        inst.twist("pull_out")

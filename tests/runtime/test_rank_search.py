"""rank's contact search (free parameters beyond the default when the hand collides there) and
the edge push (the closed fingers' nearest edge or corner, the hand unturned), checked against the
independent sweep of ``bench/bench_rank_agreement.py``."""

from __future__ import annotations

import importlib.util
import math
from dataclasses import replace
from pathlib import Path
from types import ModuleType

import numpy as np
import pytest

import grace_dsl as eac
from grace_dsl.runtime.contact import edge_points, hand_poses
from grace_dsl.runtime.gripper import Gripper
from grace_dsl.runtime.manipulation import SEARCH_TRIES, _search
from grace_dsl.runtime.symmetry import HAND_HOME

BENCH = Path(__file__).resolve().parents[2] / "bench" / "bench_rank_agreement.py"


def agreement() -> ModuleType:
    """The independent check (shares nothing with rank's geometry)."""
    spec = importlib.util.spec_from_file_location("bench_rank_agreement", BENCH)
    assert spec is not None and spec.loader is not None
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    return module


def facing_robot() -> np.ndarray:
    """The part 1 m in front of the robot, its front (+z) facing back at it, +y up."""
    m = np.eye(4)
    m[:3, :3] = np.column_stack([[0, -1, 0], [0, 0, 1], [-1, 0, 0]])
    m[:3, 3] = (1.0, 0.0, 0.8)
    return m


@pytest.mark.slow
@pytest.mark.parametrize("degrees, contact", [(85.0, "side"), (60.0, "edge")])
def test_topdown_closes_a_door_near_its_top_where_the_default_collides(
    lib: eac.Library, degrees: float, contact: str
) -> None:
    """The top-down hand pushing a cabinet door shut with a finger: at the default height (the
    door's middle) its wide palm hangs into the carcass; the search finds the top of the edge,
    where the palm clears, and the independent sweep agrees on both."""
    inst = lib["HingedCabinet"].instantiate(
        pose=facing_robot(), joints={"hinge": math.radians(degrees)}
    )
    hand = Gripper.load("topdown")
    push = next(o for o in inst.rank("close", hand) if o.grasp == "push_edge")
    assert push.feasible and push.contact == contact
    lo, hi = inst.grasp_range("push_edge")["s"]
    assert push.free["s"] > hi - 0.05 * (hi - lo)  # near the top end of the edge
    check = agreement().check
    assert check(inst, "close", push, hand)[0] is None
    # at the default (the door's middle) the same contact collides, by the other check too
    grasp = inst.grasp("push_edge")
    home = hand.home(HAND_HOME)
    hands, _ = hand_poses(hand, contact, grasp[None], home)
    oriented = hands[[int(np.argmin(hand.orientation_error(hands[:, :3, :3])[0]))]]
    at_default = replace(push, pose=grasp, hand_pose=oriented[0])
    problem, depth = check(inst, "close", at_default, hand)
    assert problem == "hand in the part on the approach" and depth > 0.005


def test_the_search_is_bounded_spread_and_in_order_of_preference() -> None:
    # ten poses on a line in the unit box, best first from the default at 0
    coords = np.linspace(0.0, 1.0, 10)[:, None]
    order = np.arange(10)
    picked = _search(order, [0, 1], coords)
    assert len(picked) == min(SEARCH_TRIES, 8)
    assert picked == sorted(picked)  # tried nearest the default first
    assert 9 in picked  # the far end comes in before the neighbours of those tried
    assert 0 not in picked and 1 not in picked
    assert _search(order, [0, 1], coords) == picked  # deterministic
    assert _search(order, [], coords) == []


def test_an_edge_push_keeps_the_fingers_on_their_side_of_the_surface() -> None:
    """Whatever the surface's normal, the closed fingers' block touches it at its support point
    and lies wholly behind the tangent plane there."""
    hand = Gripper.load("topdown")
    rng = np.random.default_rng(0)
    normals = rng.normal(size=(50, 3))
    normals /= np.linalg.norm(normals, axis=1)[:, None]
    points = edge_points(hand, normals)
    half = np.array([hand.finger_width / 2, hand.finger_thickness, hand.finger_length / 2])
    signs = np.array([[x, y, z] for x in (-1, 1) for y in (-1, 1) for z in (-1, 1)])
    corners = signs * half + np.array([0.0, 0.0, -hand.finger_length / 2])
    reach = np.einsum("ci,ni->nc", corners, normals)  # each corner along each normal
    along = np.einsum("ni,ni->n", points, normals)
    assert np.all(reach <= along[:, None] + 1e-12)
    np.testing.assert_allclose(reach.max(axis=1), along, atol=1e-12)
    # straight into the fingertips: the middle of the tips, as a tip push
    np.testing.assert_allclose(edge_points(hand, np.array([[0.0, 0.0, 1.0]]))[0], 0.0)

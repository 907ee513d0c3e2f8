"""The room and storage concepts (grace_dsl/concepts/rooms.eac, storage.eac): each opens and
closes about the joint and in the direction its synopsis describes. The expected motion of every
joint (its axis, a point on it and the way it opens, in the concept frame) is written out here from
the concepts' descriptions, not read from the compiled concept, and compared with `inst.follow`
at the defaults and at seeded random draws, at a random world pose; every action has a feasible
option for the Panda hand (`inst.rank`)."""

from __future__ import annotations

import dataclasses
from collections.abc import Callable, Mapping
from typing import Any

import numpy as np
import pytest

import grace_dsl as eac
from grace_dsl.runtime.gripper import Gripper

MM = 1e-3
Axis = tuple[str, np.ndarray, np.ndarray]  # kind, direction (opening), point on the axis


def _rev(axis: Any, at: Any = (0.0, 0.0, 0.0)) -> Axis:
    return ("revolute", np.asarray(axis, float), np.asarray(at, float))


def _pri(axis: Any) -> Axis:
    return ("prismatic", np.asarray(axis, float), np.zeros(3))


def _side(p: Mapping[str, Any]) -> float:
    return 1.0 if p["hinge_side"] == "left" else -1.0


def _tilt_turn_hub(p: Mapping[str, Any]) -> float:
    """x of the tilt-turn handle's axis: 30 mm in from the right edge of the opening."""
    return (p["size"][0] - 2 * p["frame"]) / 2 - 30 * MM


# concept -> [(opening action, closing action, joint, the joint's motion from the parameters)]
JOINTS: dict[str, list[tuple[str, str, str, Callable[[Mapping[str, Any]], Axis]]]] = {
    "ThumbTurn": [("unlock", "lock", "spin", lambda p: _rev((0, 0, 1)))],
    "SlideDimmer": [("brighten", "dim", "track", lambda p: _pri((0, 1, 0)))],
    "WindowCrank": [("wind_open", "wind_closed", "spindle", lambda p: _rev((0, 0, 1)))],
    "BlindCord": [("raise_blind", "lower_blind", "pull", lambda p: _pri((0, -1, 0)))],
    "BifoldDoor": [
        # the first leaf swings out about the left jamb at its back face
        (
            "open",
            "close",
            "hinge",
            lambda p: _rev((0, -1, 0), (-p["size"][0] / 2, 0, -p["size"][2] / 2)),
        ),
        # the second leaf folds back about the fold line on the back faces
        ("fold_up", "unfold", "fold", lambda p: _rev((0, 1, 0), (0, 0, -p["size"][2] / 2))),
    ],
    "PocketDoor": [("open", "close", "track", lambda p: _pri((-1, 0, 0)))],
    "BypassDoors": [
        ("open_front", "close_front", "slide_front", lambda p: _pri((-1, 0, 0))),
        ("open_back", "close_back", "slide_back", lambda p: _pri((1, 0, 0))),
    ],
    "SashWindow": [("open", "close", "slide", lambda p: _pri((0, 1, 0)))],
    "TiltTurnWindow": [
        # the top tips into the room about the bottom edge of the opening, level with the
        # frame's front (half the sash's thickness in front of its back)
        (
            "tilt_open",
            "tilt_close",
            "hinge",
            lambda p: _rev((1, 0, 0), (0, -(p["size"][1] - 2 * p["frame"]) / 2, p["sash"] / 2)),
        ),
        # the lever's end swings from down to left: clockwise seen from the room
        ("unlock", "lock", "turn", lambda p: _rev((0, 0, -1), (_tilt_turn_hub(p), 0, 0))),
    ],
    "RollerDoor": [("open", "close", "rise", lambda p: _pri((0, 1, 0)))],
    "FlapBox": [
        (
            "open_front",
            "close_front",
            "front_hinge",
            lambda p: _rev((1, 0, 0), (0, p["size"][1] / 2, p["size"][2] / 2)),
        ),
        (
            "open_back",
            "close_back",
            "back_hinge",
            lambda p: _rev((-1, 0, 0), (0, p["size"][1] / 2, -p["size"][2] / 2)),
        ),
    ],
    "ToolBox": [
        # the lid tips up and back about the top back edge
        (
            "open",
            "close",
            "hinge",
            lambda p: _rev((-1, 0, 0), (0, p["size"][1] / 2, -p["size"][2] / 2)),
        ),
        # the clasp's top flips out about its pivot, clasp.y below its top (15 mm over the lid)
        (
            "unlatch",
            "latch",
            "catch",
            lambda p: _rev(
                (1, 0, 0),
                (0, p["size"][1] / 2 + 15 * MM - p["clasp"][1], p["size"][2] / 2),
            ),
        ),
    ],
    "Suitcase": [("pull_up", "stow", "extend", lambda p: _pri((0, 1, 0)))],
    "KnobWardrobeDoor": [
        (
            "open",
            "close",
            "hinge",
            lambda p: _rev((0, -_side(p), 0), (-_side(p) * p["size"][0] / 2, 0, -p["size"][2] / 2)),
        )
    ],
}
# where opening moves the first grasp of the opening action, in the concept frame, at q = 0
# (the sense: the exact motion is checked against JOINTS)
OPENS_TOWARD = {
    ("WindowCrank", "spindle"): (0, 1, 0),  # the knob, on +x, rises
    ("BifoldDoor", "hinge"): (0, 0, 1),  # towards the viewer
    ("BifoldDoor", "fold"): (0, 0, -1),  # the second leaf folds back
    ("TiltTurnWindow", "hinge"): (0, 0, 1),  # into the room
    ("TiltTurnWindow", "turn"): (-1, 0, 0),  # the lever's lower end swings left
    ("FlapBox", "front_hinge"): (0, 1, 0),
    ("FlapBox", "back_hinge"): (0, 1, 0),
    ("ToolBox", "hinge"): (0, 1, 0),
    ("ToolBox", "catch"): (0, 0, 1),  # the clasp's tab comes out
    ("KnobWardrobeDoor", "hinge"): (0, 0, 1),
}
NAMES = sorted(JOINTS)
DRAWS = 3


@pytest.fixture(scope="module")
def lib() -> eac.Library:
    return eac.load_library()


def _draw(c: eac.Concept, rng: np.random.Generator) -> dict[str, Any]:
    """A random value of every parameter inside its range."""
    out: dict[str, Any] = {}
    for p in c.params:
        if p.kind == "choice":
            out[p.name] = str(rng.choice(list(p.choices)))
        elif p.kind == "bool":
            out[p.name] = bool(rng.integers(2))
        elif p.size and p.size > 1:
            out[p.name] = tuple(float(v) for v in rng.uniform(p.lo, p.hi))
        elif p.kind == "int":
            out[p.name] = int(rng.integers(int(p.lo), int(p.hi) + 1))
        else:
            out[p.name] = float(rng.uniform(p.lo, p.hi))
    return out


def _random_pose(rng: np.random.Generator) -> np.ndarray:
    q, r = np.linalg.qr(rng.normal(size=(3, 3)))
    q = q * np.sign(np.diag(r))
    if np.linalg.det(q) < 0:
        q[:, 0] = -q[:, 0]
    pose = np.eye(4)
    pose[:3, :3], pose[:3, 3] = q, rng.uniform(-1, 1, 3)
    return pose


def _instances(c: eac.Concept, seed: int) -> list[eac.Instance]:
    """The defaults at the identity, and up to DRAWS valid random draws at random poses."""
    rng = np.random.default_rng(seed)
    out = [c.instantiate()]
    for _ in range(8 * DRAWS):
        if len(out) > DRAWS:
            break
        try:
            out.append(c.instantiate(pose=_random_pose(rng), **_draw(c, rng)))
        except eac.RequirementError:
            continue
    return out


def _motion(axis: Axis, q: float) -> np.ndarray:
    """The rigid motion, in the concept frame, of a link whose joint moves by q (Rodrigues)."""
    kind, a, o = axis
    a = a / np.linalg.norm(a)
    m = np.eye(4)
    if kind == "prismatic":
        m[:3, 3] = q * a
        return m
    k = np.array([[0, -a[2], a[1]], [a[2], 0, -a[0]], [-a[1], a[0], 0]])
    r = np.eye(3) + np.sin(q) * k + (1 - np.cos(q)) * (k @ k)
    m[:3, :3], m[:3, 3] = r, o - r @ o
    return m


def _assert_same_grasp(spec: Any, got: np.ndarray, want: np.ndarray) -> None:
    """Equal poses; for a symmetric grasp, whose spin the runtime picks anew at every pose,
    the same point and symmetry axis (the approach z, or x for BlindCord's tassel)."""
    if not spec.symmetric:
        np.testing.assert_allclose(got, want, atol=1e-6)
        return
    column = 2 if spec.approach_symmetric else 0
    np.testing.assert_allclose(got[:3, 3], want[:3, 3], atol=1e-6)
    np.testing.assert_allclose(got[:3, column], want[:3, column], atol=1e-6)


def _target(inst: eac.Instance, joint: str) -> float:
    lo, hi = inst.joint_limits()[joint]
    return 0.6 * hi if np.isfinite(hi) else 1.0


@pytest.mark.parametrize("name", NAMES)
def test_open_then_close_moves_the_joint_as_described(lib: eac.Library, name: str) -> None:
    c = lib[name]
    for inst in _instances(c, seed=7):
        world = inst.pose
        for opening, closing, joint, axis_of in JOINTS[name]:
            assert c.actions[opening]["joint"] == joint == c.actions[closing]["joint"]
            assert c.actions[opening]["sense"] == "opening"
            assert c.actions[closing]["sense"] == "closing"
            q1 = _target(inst, joint)
            grasp = c.actions[opening]["using"][0]
            start = inst.grasp(grasp)
            opened = inst.follow(opening, grasp=start, to=q1)
            expected = world @ _motion(axis_of(inst.params), q1) @ np.linalg.inv(world) @ start
            np.testing.assert_allclose(opened[0], start, atol=1e-9)
            np.testing.assert_allclose(opened[-1], expected, atol=1e-6)
            # the link at q1 carries the grasp where the path ends
            moved = inst.with_joints({joint: q1})
            _assert_same_grasp(c.grasps[grasp], moved.grasp(grasp), expected)
            toward = OPENS_TOWARD.get((name, joint))
            if toward is not None:  # the first small step goes the way the synopsis says
                step = inst.follow(opening, grasp=start, to=1e-3 * q1, steps=2)
                local = np.linalg.solve(world[:3, :3], step[1][:3, 3] - step[0][:3, 3])
                assert local @ np.asarray(toward, float) > 0.1 * np.linalg.norm(local)
            # closing brings the grasp back, and cannot open further
            closed = moved.follow(closing, grasp=opened[-1], to=0.0)
            np.testing.assert_allclose(closed[-1], start, atol=1e-6)
            with pytest.raises(eac.ParameterError):
                moved.follow(closing, grasp=opened[-1], to=q1 + 1e-2)
            with pytest.raises(eac.ParameterError):
                moved.follow(opening, grasp=opened[-1], to=0.0)


def _mid_joints(inst: eac.Instance) -> dict[str, float]:
    return {
        j: (lo + hi) / 2 if np.isfinite(hi - lo) else 0.3
        for j, (lo, hi) in inst.joint_limits().items()
    }


# Leaves on parallel tracks: both half open puts them exactly behind each other, so the back
# leaf's pull is out of reach. Each leaf is judged half open with the other one closed.
ONE_AT_A_TIME = {"BypassDoors"}


def _half_open_states(inst: eac.Instance) -> list[eac.Instance]:
    mid = _mid_joints(inst)
    if inst.concept.name not in ONE_AT_A_TIME:
        return [inst.with_joints(mid)]
    closed = {j: 0.0 for j in mid}
    return [inst.with_joints({**closed, j: q}) for j, q in mid.items()]


@pytest.mark.parametrize("name", NAMES)
def test_every_action_has_a_feasible_panda_option(lib: eac.Library, name: str) -> None:
    """Every action, at two draws half open, has an option the Panda's whole hand (pads,
    finger blocks, palm) can do over the approach and the path."""
    c = lib[name]
    for inst in _instances(c, seed=11)[:2]:
        for half_open in _half_open_states(inst):
            for action in c.actions:
                joint = c.actions[action]["joint"]
                if name in ONE_AT_A_TIME and joint and half_open.joints[joint] == 0.0:
                    continue  # this leaf is judged in its own state
                options = half_open.rank(action, Gripper.panda(), samples=8)
                assert any(o.feasible for o in options), (
                    name,
                    action,
                    [(o.grasp, o.reasons) for o in options],
                )


# doors, lids, sashes and handles that a hand which cannot close shuts by pushing
CLOSED_BY_PUSH = {
    "BifoldDoor": "close",
    "KnobWardrobeDoor": "close",
    "TiltTurnWindow": "tilt_close",
    "SashWindow": "close",
    "RollerDoor": "close",
    "FlapBox": "close_front",
    "ToolBox": "close",
    "Suitcase": "stow",
    "SlideDimmer": "dim",
    "ThumbTurn": "lock",
}


@pytest.mark.parametrize("name", sorted(CLOSED_BY_PUSH))
def test_a_hand_that_cannot_close_shuts_by_pushing(lib: eac.Library, name: str) -> None:
    c = lib[name]
    no_close = dataclasses.replace(Gripper.panda(), can_close=False)
    inst = c.instantiate(joints=_mid_joints(c.instantiate()))
    best = inst.rank(CLOSED_BY_PUSH[name], no_close, samples=8)[0]
    assert best.feasible and c.grasps[best.grasp]["mode"] == "push", (name, best)


def test_the_pinches_fit_a_panda_hand_and_pushes_do_not_pinch(lib: eac.Library) -> None:
    for name in NAMES:
        c = lib[name]
        for inst in _instances(c, seed=3):
            for g, entry in c.grasps.items():
                w = inst.grasp_width(g)
                if entry.get("mode", "pinch") == "pinch":
                    assert w is not None and 0 < w <= 0.080, (name, g, w)

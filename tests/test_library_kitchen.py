"""The kitchen and bathroom concepts (grace_dsl/concepts/kitchen.eac, bathroom.eac): each
instantiates at its defaults and at seeded random draws, its opening actions move the grasp the
way the physical object opens (a direction written here from the object, not from the concept's
formulas) and its closing actions move it back, a followed path ends where the link's own pose
at the final joint value carries the grasp, and every action has a feasible manipulation
function for the Panda hand."""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest

import grace_dsl as eac
from grace_dsl.runtime.gripper import Gripper

# concept -> {opening action: (its closing action, the direction in the concept frame in which the
# grasp point of the first grasp the action uses starts to move when the closed object opens;
# for a grasp on a turning axis, the axis the hand turns about)}
OPENS = {
    "StoveKnob": {
        "push_in": ("release", (0, 0, -1)),  # into the panel
        "turn_on": ("turn_off", (0, 0, 1)),  # counter-clockwise seen from the front (a twist)
    },
    "KitchenMixer": {
        "turn_on": ("turn_off", (0, 1, 0)),  # the lever's tip lifts
        "warmer": ("cooler", (-1, 0, 0)),  # the tip swings to the user's left
    },
    "Toaster": {"start": ("cancel", (0, -1, 0))},  # the carriage lever goes down
    "Kettle": {"open": ("close", (0, 1, 0))},  # the lid's front lifts
    "PedalBin": {
        "step_on": ("step_off", (0, -1, 0)),  # the pedal goes down
        "open": ("close", (0, 1, 0)),  # the lid's front lifts
    },
    "RangeHood": {"open": ("close", (0, 0, 1))},  # the visor slides out towards the cook
    "BreadBin": {"open": ("close", (0, 1, 0))},  # the roll's front edge rises
    "ChestFreezer": {"open": ("close", (0, 1, 0))},
    "DishDrawer": {"open": ("close", (0, 0, 1))},
    "ToasterOven": {"open": ("close", (0, 0, 1))},  # the top of the door falls towards the viewer
    "KeyRow": {
        "press1": ("release1", (0, 0, -1)),
        "press2": ("release2", (0, 0, -1)),
        "press3": ("release3", (0, 0, -1)),
    },
    "FlushLever": {"flush": ("release", (0, -1, 0))},  # the arm's free end goes down
    "ShowerMixer": {"turn_on": ("turn_off", (1, 0, 0))},  # the lever hanging down swings right
    "MirrorCabinet": {"open": ("close", (0, 0, 1))},  # the free edge swings out of the wall
    "CoffeeMachine": {
        "open_lid": ("close_lid", (0, 1, 0)),
        "pull_tray": ("push_tray_in", (0, 0, 1)),
    },
    "TopLoadWasher": {"open": ("close", (0, 1, 0))},
    "ShowerDoor": {"open": ("close", (0, 0, 1))},  # the door swings out of the shower
}
KITCHEN = sorted(OPENS)
DRAWS = 12
# Keys spring back by themselves: the hand only withdraws, which no contact of a press grasp
# can drive (`rank` says why). These closing actions have no feasible option, by design.
SPRING_RETURN = {("KeyRow", "release1"), ("KeyRow", "release2"), ("KeyRow", "release3")}


@pytest.fixture(scope="module")
def lib() -> eac.Library:
    return eac.load_library()


def _draw(c: eac.Concept, rng: np.random.Generator) -> dict[str, object]:
    out: dict[str, object] = {}
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


def _instances(c: eac.Concept, seed: int) -> list[eac.Instance]:
    """The defaults and the valid ones of ``DRAWS`` seeded draws."""
    rng = np.random.default_rng(seed)
    out = [c.instantiate()]
    for _ in range(DRAWS):
        try:
            out.append(c.instantiate(**_draw(c, rng)))
        except eac.RequirementError:
            continue
    return out


def test_the_concepts_are_in_the_library(lib: eac.Library) -> None:
    files = {lib[n].entry["file"] for n in KITCHEN}
    assert files == {"kitchen.eac", "bathroom.eac"}
    for name in KITCHEN:
        c = lib[name]
        assert c.doc.strip() and c.grasps
        joint_actions = {a for a, e in c.actions.items() if e["joint"]}
        listed = set(OPENS[name]) | {close for close, _ in OPENS[name].values()}
        assert listed == joint_actions, f"{name}: the table here misses {joint_actions - listed}"
        for opening, (closing, _) in OPENS[name].items():
            assert c.actions[opening]["sense"] == "opening"
            assert c.actions[closing]["sense"] == "closing"
            assert c.actions[opening]["joint"] == c.actions[closing]["joint"]


@pytest.mark.parametrize("name", KITCHEN)
def test_valid_draws_are_common(lib: eac.Library, name: str) -> None:
    """At least a fifth of uniform draws inside the ranges meet the requirements."""
    valid = len(_instances(lib[name], seed=3)) - 1
    assert valid >= DRAWS // 5, f"{name}: {valid} of {DRAWS} draws are valid"


def _rotation_vector(r: np.ndarray) -> np.ndarray:
    """Axis times angle of a rotation matrix (angles below 180 degrees), from its skew part."""
    angle = np.arccos(np.clip((np.trace(r) - 1) / 2, -1.0, 1.0))
    skew = np.array([r[2, 1] - r[1, 2], r[0, 2] - r[2, 0], r[1, 0] - r[0, 1]])
    n = np.linalg.norm(skew)
    return np.zeros(3) if n < 1e-12 else angle * skew / n


def _check_path(
    inst: eac.Instance, action: str, grasp_name: str, q0: float, q1: float
) -> np.ndarray:
    """Follow ``action`` from q0 to q1 with the grasp held; check the path's end against the
    grasp's link posed independently at q1 (a fresh instance), and return the path."""
    c = inst.concept
    joint = c.actions[action]["joint"]
    link = c.grasps[grasp_name].link
    start = c.instantiate(**inst.params, joints={**inst.joints, joint: q0})
    end = c.instantiate(**inst.params, joints={**inst.joints, joint: q1})
    g0 = start.grasp(grasp_name)
    path = start.follow(action, grasp=g0, to=q1, steps=5)
    assert np.allclose(path[0], g0, atol=1e-9)
    carried = end.link_pose(link) @ np.linalg.inv(start.link_pose(link)) @ g0
    assert np.allclose(path[-1], carried, atol=1e-7), f"{c.name}.{action}: path end is off"
    assert np.allclose(path[-1], end.grasp(grasp_name), atol=1e-7)
    return path


def _motion(path: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """The first step of a path: the grasp point's displacement and the hand's rotation."""
    step = path[1][:3, 3] - path[0][:3, 3]
    turn = _rotation_vector(path[1][:3, :3] @ path[0][:3, :3].T)
    return step, turn


@pytest.mark.parametrize("name", KITCHEN)
def test_open_then_close_moves_the_object_the_right_way(lib: eac.Library, name: str) -> None:
    c = lib[name]
    for inst in _instances(c, seed=7):
        limits = inst.joint_limits()
        for opening, (closing, expected) in OPENS[name].items():
            joint = c.actions[opening]["joint"]
            lo, hi = limits[joint]
            assert lo == 0.0 and hi > 0.0, f"{name}.{joint}: q = 0 is closed, positive opens"
            want = np.asarray(expected, float)
            grasp = c.actions[opening]["using"][0]
            opened = _check_path(inst, opening, grasp, 0.0, hi)
            step, turn = _motion(opened)
            if np.linalg.norm(step) < 1e-9:  # a grasp on the turning axis: the hand turns
                assert turn @ want > 0.99 * np.linalg.norm(turn) > 0, (name, opening, turn)
            else:
                assert step @ want > 0.5 * np.linalg.norm(step), (name, opening, step)
            # closing from the open end retraces the opening path back to q = 0
            closed = _check_path(inst, closing, grasp, hi, 0.0)
            assert np.allclose(closed[::-1], opened, atol=1e-7), (name, closing)


@pytest.mark.parametrize("name", KITCHEN)
def test_every_action_has_a_feasible_option_for_the_panda(lib: eac.Library, name: str) -> None:
    """At the defaults and half open, the Panda hand can do every action some way; every grasp
    an action names is judged."""
    c = lib[name]
    closed = c.instantiate()
    half = {j: (lo + hi) / 2 for j, (lo, hi) in closed.joint_limits().items()}
    for inst in (closed, c.instantiate(joints=half)):
        for action, entry in c.actions.items():
            options = inst.rank(action, Gripper.panda(), samples=8)
            assert {o.grasp for o in options} == set(entry["using"])
            if (name, action) in SPRING_RETURN:
                assert not options[0].feasible and "180 deg" in options[0].reasons[0]
                continue
            assert options[0].feasible, (name, action, [o.reasons for o in options])


@pytest.mark.parametrize("name", KITCHEN)
def test_a_closed_hand_can_close_what_it_opened(lib: eac.Library, name: str) -> None:
    """Concepts whose closing action lists a push or press can be closed by a hand that cannot
    close its fingers (a pusher), half open."""
    c = lib[name]
    pusher = dataclasses.replace(Gripper.panda(), can_close=False)
    half = {j: (lo + hi) / 2 for j, (lo, hi) in c.instantiate().joint_limits().items()}
    inst = c.instantiate(joints=half)
    for _, (closing, _) in OPENS[name].items():
        modes = {c.grasps[g].mode for g in c.actions[closing]["using"]}
        best = inst.rank(closing, pusher, samples=8)[0]
        can = bool(modes & {"push", "press", "hook"}) and (name, closing) not in SPRING_RETURN
        assert best.feasible == can, (name, closing, best)

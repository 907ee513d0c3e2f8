"""Hands: the description format, orientation cones, the wrist, the whole hand's geometry and
force transmission per contact, as ``rank`` judges them."""

from __future__ import annotations

import dataclasses
import json
import math
import xml.etree.ElementTree as ET
from pathlib import Path

import numpy as np
import pytest

import grace_dsl as eac
from grace_dsl.errors import GraceError
from grace_dsl.runtime.contact import rotation_from
from grace_dsl.runtime.gripper import Gripper, HandBox
from grace_dsl.runtime.hands import HandFileError, parse_hand
from grace_dsl.runtime.symmetry import HAND_HOME
from tests.conftest import write

MINIMAL = """
name = "mine"
max_width = "60 mm"
[pad]
size = "20 10 25 mm"
"""


def _top(line: str) -> str:
    """MINIMAL with a top-level key added (on line 4, before the [pad] table)."""
    return MINIMAL.replace("[pad]", line + "\n[pad]")


def facing_robot() -> np.ndarray:
    """The part 1 m in front of the robot, its front (+z) facing back at it (-x world), +y up."""
    m = np.eye(4)
    m[:3, :3] = np.column_stack([[0, -1, 0], [0, 0, 1], [-1, 0, 0]])
    m[:3, 3] = (1.0, 0.0, 0.8)
    return m


# ---- the format ---------------------------------------------------------------------------------


def test_every_shipped_hand_loads_by_name_and_by_path() -> None:
    names = Gripper.shipped()
    assert {"panda", "topdown", "pusher"} <= set(names)
    for name in names:
        hand = Gripper.load(name)
        assert hand.name == name
        path = Path(eac.__file__).parent / "hands" / f"{name}.toml"
        assert Gripper.load(path) == hand == Gripper.load(str(path))
    assert Gripper.panda() == Gripper.load("panda")
    pusher = Gripper.load("pusher")
    assert not pusher.can_close and pusher.max_width == 0.0
    top = Gripper.load("topdown")
    assert not top.can_turn and top.approach == (0.0, 0.0, -1.0)


def test_the_panda_numbers_are_those_of_example_robot_data() -> None:
    """Read the URDF independently: finger travel, the tip box, the finger blocks."""
    root = ET.parse(_panda_urdf()).getroot()
    joint = root.find("joint[@name='panda_finger_joint1']")
    assert joint is not None
    travel = float(joint.find("limit").attrib["upper"])  # type: ignore[union-attr]
    origin_z = float(joint.find("origin").attrib["xyz"].split()[2])  # type: ignore[union-attr]
    hand = Gripper.panda()
    assert hand.max_width == pytest.approx(2 * travel)
    boxes = []
    for col in root.find("link[@name='panda_leftfinger']").findall("collision"):  # type: ignore[union-attr]
        xyz = [float(v) for v in col.find("origin").attrib["xyz"].split()]  # type: ignore[union-attr]
        rpy = [float(v) for v in col.find("origin").attrib["rpy"].split()]  # type: ignore[union-attr]
        size = [float(v) for v in col.find("geometry/box").attrib["size"].split()]  # type: ignore[union-attr]
        boxes.append((xyz, rpy, size))
    tip = next(b for b in boxes if b[2][2] == pytest.approx(18.5e-3))
    assert (hand.finger_width, hand.finger_thickness, hand.finger_length) == pytest.approx(tip[2])
    tip_end = origin_z + tip[0][2] + tip[2][2] / 2  # gripper origin: the tips' ends
    for xyz, rpy, size in boxes:
        if size == tip[2]:
            continue
        match = [b for b in hand.fingers if np.allclose(2 * np.array(b.half_extents), size)]
        assert len(match) == 1, size
        b = match[0]
        np.testing.assert_allclose(
            b.center, (xyz[0], xyz[1], origin_z + xyz[2] - tip_end), atol=1e-4
        )
        np.testing.assert_allclose(b.rpy, rpy, atol=1e-4)


def test_the_panda_palm_holds_the_hand_mesh() -> None:
    """Every vertex of example-robot-data's hand collision mesh below the finger joints' plane
    lies in one of the palm boxes (the mesh read with trimesh, moved to the gripper frame)."""
    import trimesh

    mesh = trimesh.load(_panda_urdf().parents[1] / "meshes" / "collision" / "hand.stl")
    v = np.asarray(mesh.vertices)
    v = v[v[:, 2] <= 0.0584 + 1e-9] - (0.0, 0.0, 0.1129)  # tips end 112.9 mm from panda_hand
    inside = np.zeros(len(v), bool)
    for box in Gripper.panda().palm:
        local = np.abs(v - np.array(box.center))
        inside |= np.all(local <= np.array(box.half_extents) + 5e-4, axis=1)
    assert inside.all(), v[~inside]


def _panda_urdf() -> Path:
    from grace_dsl.robot.model import robot_data_file

    return Path(robot_data_file("panda_description/urdf/panda.urdf"))


def test_a_user_hand_in_other_units_is_the_same_hand(tmp_path: Path) -> None:
    mm = parse_hand(MINIMAL)
    cm = parse_hand(MINIMAL.replace('"60 mm"', '"6 cm"').replace('"20 10 25 mm"', '"2 1 2.5 cm"'))
    assert dataclasses.replace(cm) == mm
    assert (mm.max_width, mm.finger_width, mm.finger_thickness) == pytest.approx((0.06, 0.02, 0.01))
    assert mm.can_close and mm.can_turn and mm.approach is None and mm.palm == ()
    path = write(tmp_path, "mine.toml", MINIMAL)
    assert Gripper.load(path) == mm


@pytest.mark.parametrize(
    ("text", "key", "line", "words"),
    [
        (_top("colour = 'red'"), "colour", 4, "unknown key"),
        (MINIMAL.replace("[pad]", "[pad]\nsise = '1 mm'"), "pad.sise", 5, "did you mean"),
        (MINIMAL.replace('"60 mm"', '"60 deg"'), "max_width", 3, "wrong unit 'deg'"),
        (MINIMAL.replace('"60 mm"', '"60"'), "max_width", 3, "has no unit"),
        (MINIMAL.replace('"60 mm"', "60"), "max_width", 3, "with its unit"),
        (MINIMAL.replace('"60 mm"', '"-60 mm"'), "max_width", 3, "non-negative"),
        (MINIMAL.replace('"20 10 25 mm"', '"20 -10 25 mm"'), "pad.size", 5, "positive"),
        (MINIMAL.replace('"20 10 25 mm"', '"20 10 mm"'), "pad.size", 5, "expected 3 numbers"),
        (MINIMAL.replace('"20 10 25 mm"', '"20 10 2e5x mm"'), "pad.size", 5, "expected 3"),
        (MINIMAL.replace('name = "mine"', "name = 3"), "name", 2, "text in quotes"),
        (MINIMAL.replace('name = "mine"\n', ""), "name", None, "missing"),
        (_top("can_turn = 'yes'"), "can_turn", 4, "true or false"),
        (MINIMAL + "[orientation]\napproach = [0, 0, 0]\n", "orientation.approach", 7, "not all 0"),
        (
            MINIMAL + "[orientation]\napproach_tolerance = '5 mm'\n",
            "orientation.approach_tolerance",
            7,
            "wrong unit 'mm'",
        ),
        (MINIMAL + "[[palm]]\nsize = '1 1 1 mm'\n", "palm[0].at", 6, "missing"),
        (
            MINIMAL
            + "[[finger]]\nsize = '1 1 1 mm'\nat = '0 0 0 mm'\n[[finger]]\nsize = '0 1 1 mm'\n"
            "at = '0 0 0 mm'\n",
            "finger[1].size",
            10,
            "positive",
        ),
        (_top("pushes = ['elbow']"), "pushes", 4, "tip, side, palm"),
        (
            MINIMAL.replace("[pad]", "can_close = true\n[pad]").replace('"60 mm"', '"0 mm"'),
            "max_width",
            3,
            "can_close",
        ),
        (_top("format = 2"), "format", 4, "format 1"),
    ],
)
def test_bad_files_name_the_key_and_the_line(
    text: str, key: str, line: int | None, words: str
) -> None:
    with pytest.raises(HandFileError) as info:
        parse_hand(text, "my.toml")
    err = info.value
    assert isinstance(err, GraceError) and isinstance(err, eac.ParameterError)
    assert (err.key, err.line) == (key, line)
    assert words in str(err) and str(err).startswith("my.toml")


def test_text_that_is_not_toml_is_located() -> None:
    with pytest.raises(HandFileError, match=r"my.toml:3: not TOML"):
        parse_hand('name = "x"\nmax_width = "1 mm"\n[pad\n', "my.toml")


def test_unknown_hands_and_missing_files_are_typed_errors(tmp_path: Path) -> None:
    with pytest.raises(eac.ParameterError, match="no shipped hand 'pand'.*did you mean"):
        Gripper.load("pand")
    with pytest.raises(eac.ParameterError, match="cannot read hand file"):
        Gripper.load(tmp_path / "none.toml")
    with pytest.raises(eac.ParameterError, match="shipped name"):
        Gripper.load(3)  # type: ignore[arg-type]


def test_the_hand_boxes_mirror_and_open() -> None:
    hand = Gripper.panda()
    closed, wide = hand.hand_boxes(0.0), hand.hand_boxes(0.06)
    assert [b.part for b in closed] == ["pad"] * 2 + ["finger"] * 6 + ["palm"] * 2
    for a, b in zip(closed, wide):  # fingers move out by half the opening, the palm stays
        shift = 0.0 if a.part == "palm" else math.copysign(0.03, a.pose[1, 3])
        np.testing.assert_allclose(b.pose[:3, 3] - a.pose[:3, 3], (0, shift, 0), atol=1e-12)
    diag = [b for b in closed if b.name == "diagonal"]
    np.testing.assert_allclose(
        diag[0].pose[:3, :3] @ np.diag([1, -1, 1]),
        np.diag([1, -1, 1]) @ diag[1].pose[:3, :3],
        atol=1e-12,
    )


# ---- concepts for the hands ---------------------------------------------------------------------

KNOB_AND_FRONT = """use primitives.{Cuboid, Cylinder}

/// A knob with a fin across its face, on a fixed base.
concept FinKnob {
    param radius : length in [10mm, 40mm] = 20mm
    link knob {
        shape body = Cylinder(radius: radius, height: 20mm)
        shape ridge = Cuboid(size: (1.6 * radius, 8mm, 10mm)) at trans(0, 0, 15mm)
        /// Pinch the fin across its thickness, from the front.
        grasp fin = trans(0, 0, 15mm) * roty(180deg) width 8mm
        /// Pinch the round body from the front at any spin.
        grasp rim = roty(180deg) width 2 * radius symmetric
    }
    joint mount : fixed(base -> knob)
    /// Pull the knob off.
    action pull_off = pull toward (0, 0, 1) using fin, rim
}

/// A drawer front board on a slide, pushed shut at two heights.
concept Front {
    param size : vec3 length in [(200mm, 100mm, 10mm), (900mm, 400mm, 40mm)] = (400mm, 150mm, 20mm)
    link board {
        shape plate = Cuboid(size: size)
        /// Push the face 15 mm above the bottom edge.
        grasp push_low = trans(0, -size.y / 2 + 15mm, size.z / 2) * roty(180deg) by push
        /// Push the face 15 mm below the top edge.
        grasp push_high = trans(0, size.y / 2 - 15mm, size.z / 2) * roty(180deg) by push
        /// Pinch the top edge, from above.
        grasp top = trans(0, size.y / 2, 0) * rotx(90deg) * rotz(90deg) width size.z
    }
    joint slide : prismatic(base -> board) axis (0, 0, 1) range [0, 300mm] opens +
    /// Push the drawer shut.
    action close = push along slide using push_low, push_high, top
    /// Pull it open.
    action open = pull along slide using push_low, push_high, top
}
"""


@pytest.fixture(scope="module")
def parts(tmp_path_factory: pytest.TempPathFactory) -> eac.Library:
    return eac.compile_paths([write(tmp_path_factory.mktemp("hands"), "parts.eac", KNOB_AND_FRONT)])


def _by_grasp(options: tuple[eac.Option, ...]) -> dict[str, eac.Option]:
    return {o.grasp: o for o in options}


def test_a_top_down_hand_cannot_turn_its_fingers_to_a_fin(parts: eac.Library) -> None:
    """Face up, the fin's pinch closes along world y: the top-down hand's axis. Turned a quarter
    about the knob's axis, its tilt is still 0 but its fingers would have to close 90 deg off."""
    top = Gripper.load("topdown")
    aligned = _by_grasp(parts["FinKnob"].instantiate().rank("pull_off", top))
    assert aligned["fin"].feasible and aligned["fin"].tilt == pytest.approx(0, abs=1e-9)
    assert aligned["fin"].rotation == pytest.approx(0, abs=1e-6)
    turned = np.eye(4)
    turned[:3, :3] = [[0, -1, 0], [1, 0, 0], [0, 0, 1]]
    options = _by_grasp(parts["FinKnob"].instantiate(pose=turned).rank("pull_off", top))
    fin = options["fin"]
    assert fin.tilt == pytest.approx(0, abs=1e-9) and fin.turn == pytest.approx(math.pi / 2)
    assert not fin.feasible and "close 90 deg from where they can" in fin.reasons[0]
    # the rim is symmetric about the approach: spun to where the hand can close, it works
    assert options["rim"].feasible and options["rim"].turn == pytest.approx(0, abs=1e-6)
    # the whole rotation of the hand is what rank scores: the angle from the hand's home
    home = top.home(HAND_HOME)
    assert fin.rotation == pytest.approx(float(rotation_from(home, fin.hand_pose[:3, :3])))
    assert fin.rotation == pytest.approx(math.pi / 2)
    # the Panda turns its wrist: both work for it
    assert all(o.feasible for o in parts["FinKnob"].instantiate(pose=turned).rank("pull_off"))


def test_a_twist_needs_a_wrist_that_turns(lib: eac.Library) -> None:
    dial = lib["RotaryDial"].instantiate(pose=np.eye(4))  # face up, reached from above
    panda = _by_grasp(dial.rank("turn_on", Gripper.panda()))
    assert panda["twist"].feasible
    stiff = dataclasses.replace(Gripper.panda(), name="stiff", can_turn=False)
    options = _by_grasp(dial.rank("turn_on", stiff))
    assert not options["twist"].feasible
    assert "turns the hand in place, and stiff's wrist cannot turn" in options["twist"].reasons[0]
    # gripping off the axis moves the hand round, but a pinch still turns it with the dial
    assert not options["grip"].feasible and "wrist cannot turn" in options["grip"].reasons[0]
    for o in dial.rank("turn_on", Gripper.load("topdown")):
        assert not o.feasible and "cannot turn" in " ".join(o.reasons)


def test_a_palm_wider_than_the_fingers_cannot_push_low_on_a_front(parts: eac.Library) -> None:
    """The top-down hand pushes a front shut with the side of its fingers; 15 mm above the
    bottom edge its palm, reaching 50 mm beyond the fingers, would be inside the board."""
    front = parts["Front"].instantiate(pose=facing_robot(), joints={"slide": 0.2})
    top = Gripper.load("topdown")
    options = _by_grasp(front.rank("close", top))
    high, low = options["push_high"], options["push_low"]
    assert high.feasible and high.contact == "side"
    assert not low.feasible and "by side: the palm enters the part" in low.reasons[0]
    # the side face touches the contact point and pushes along the contact's +z
    local = np.linalg.solve(high.hand_pose, np.append(high.pose[:3, 3], 1.0))[:3]
    assert abs(local[0]) == pytest.approx(top.finger_width / 2) and local[1] == pytest.approx(0)
    normal = high.hand_pose[:3, :3].T @ high.pose[:3, 2]
    np.testing.assert_allclose(normal, (math.copysign(1, local[0]), 0, 0), atol=1e-9)
    np.testing.assert_allclose(high.hand_pose[:3, 2], (0, 0, -1), atol=1e-9)  # from above
    # with a palm no wider than the fingers, the low push works too
    narrow = dataclasses.replace(
        top, palm=(HandBox("palm", (0.0, 0.0, -0.085), (0.01, 0.07, 0.02)),)
    )
    assert _by_grasp(front.rank("close", narrow))["push_low"].feasible


def test_a_palm_push(parts: eac.Library) -> None:
    """A hand whose palm stands in front of its fingers pushes with the palm: a mode of its own,
    only pushing, never pulling."""
    paddle = parse_hand(
        """name = "paddle"
max_width = "0 mm"
can_close = false
pushes = ["palm"]
[pad]
size = "10 5 10 mm"
[[palm]]
size = "100 100 10 mm"
at = "0 0 5 mm"
"""
    )
    front = parts["Front"].instantiate(pose=facing_robot(), joints={"slide": 0.2})
    close = _by_grasp(front.rank("close", paddle))
    assert close["push_low"].feasible and close["push_low"].contact == "palm"
    hand = close["push_low"].hand_pose
    np.testing.assert_allclose(hand[:3, 2], close["push_low"].pose[:3, 2], atol=1e-12)
    np.testing.assert_allclose(  # the palm's face, 10 mm ahead of the tips, on the contact
        np.linalg.solve(hand, np.append(close["push_low"].pose[:3, 3], 1))[:3],
        (0, 0, 0.01),
        atol=1e-12,
    )
    assert not close["top"].feasible and "needs fingers that close" in close["top"].reasons[0]
    pull = _by_grasp(front.rank("open", paddle))
    assert not pull["push_low"].feasible
    assert "cannot apply the force of open" in pull["push_low"].reasons[0]


def test_force_transmission_per_contact(parts: eac.Library) -> None:
    """A pinch holds both ways; a push only pushes (by any part of the hand)."""
    front = parts["Front"].instantiate(pose=np.eye(4), joints={"slide": 0.2})
    for action in ("open", "close"):
        assert _by_grasp(front.rank(action))["top"].feasible
    opening = _by_grasp(front.rank("open"))
    for name in ("push_low", "push_high"):
        assert not opening[name].feasible
        assert "deg from the fingers' approach" in opening[name].reasons[0]


def test_ties_prefer_the_default_free_parameters(lib: eac.Library) -> None:
    """Every pinch along a straight bar needs the same rotation: the default (the middle) wins,
    even when the samples miss it."""
    drawer = lib["CabinetDrawer"].instantiate(pose=facing_robot())
    for samples in (4, 32):
        best = _by_grasp(drawer.rank("open", samples=samples))["handle.pull"]
        assert best.feasible and best.free == {"s": 0.0}
        np.testing.assert_allclose(best.pose, drawer.grasp("handle.pull"), atol=1e-12)


# ---- the documentation and eacc verify --------------------------------------------------------


def test_the_documented_example_file_is_the_shipped_topdown_hand() -> None:
    api = (Path(__file__).resolve().parents[2] / "docs" / "api.md").read_text()
    block = api.split("### Hand description files", 1)[1].split("```toml\n", 1)[1].split("```")[0]
    documented = parse_hand(block, "docs/api.md")
    shipped = Gripper.load("topdown")
    assert dataclasses.replace(documented, doc=shipped.doc) == shipped


def test_eacc_verify_takes_a_hand(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    from grace_dsl.cli.eacc import main
    from grace_dsl.runtime.verify import VerifyReport

    argv = ["verify", "--concept", "RoundKnob", "--draws", "2", "--json"]
    assert main([*argv, "--gripper", "topdown"]) == 0
    assert VerifyReport.from_json(json.loads(capsys.readouterr().out)).gripper == "topdown"
    path = write(tmp_path, "mine.toml", MINIMAL)
    assert main([*argv, "--gripper", str(path)]) == 0
    assert VerifyReport.from_json(json.loads(capsys.readouterr().out)).gripper == "mine"
    assert main([*argv, "--gripper", "pandda"]) == 2
    assert "no shipped hand 'pandda'" in capsys.readouterr().err
    bad = write(tmp_path, "bad.toml", MINIMAL.replace('"60 mm"', '"60 deg"'))
    assert main([*argv, "--gripper", str(bad)]) == 2
    assert "bad.toml:3: max_width: wrong unit" in capsys.readouterr().err


@pytest.mark.slow
@pytest.mark.parametrize("hand", ["topdown", "pusher"])
def test_the_standard_library_verifies_for_every_shipped_hand(hand: str, lib: eac.Library) -> None:
    """`eacc verify --gripper HAND` is clean (the Panda's run is in test_verify.py)."""
    from grace_dsl.runtime.verify import verify_library

    report = verify_library(lib, draws=3, seed=0, gripper=Gripper.load(hand))
    assert report.ok, [(f.concept, f.check, f.member, f.message) for f in report.failures]
    assert report.gripper == hand


def test_the_rotation_score_is_a_geodesic_angle_up_to_the_half_turn() -> None:
    """rotation_from: the angle of R_home^T R (trace formula checked against the axis-angle
    rotation that produced it), the same for R turned half a turn about its approach."""
    rng = np.random.default_rng(7)
    half = np.diag([-1.0, -1.0, 1.0])
    for _ in range(50):
        axis = rng.normal(size=3)
        axis /= np.linalg.norm(axis)
        theta = float(rng.uniform(0, math.pi / 2))  # below 90 deg the half turn is farther
        k = np.array([[0, -axis[2], axis[1]], [axis[2], 0, -axis[0]], [-axis[1], axis[0], 0]])
        turn = np.eye(3) + math.sin(theta) * k + (1 - math.cos(theta)) * k @ k
        home = np.linalg.qr(rng.normal(size=(3, 3)))[0]
        home *= np.sign(np.linalg.det(home))
        r = home @ turn
        assert float(rotation_from(home, r)) == pytest.approx(theta, abs=1e-7)
        assert float(rotation_from(home, r @ half)) == pytest.approx(theta, abs=1e-7)

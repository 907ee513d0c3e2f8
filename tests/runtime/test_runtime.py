"""The runtime API against independent computations (numpy, finite differences)."""

from __future__ import annotations

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

import grace_dsl as eac


def rot(axis: str, a: float) -> np.ndarray:
    c, s = np.cos(a), np.sin(a)
    m = {
        "x": [[1, 0, 0], [0, c, -s], [0, s, c]],
        "y": [[c, 0, s], [0, 1, 0], [-s, 0, c]],
        "z": [[c, -s, 0], [s, c, 0], [0, 0, 1]],
    }[axis]
    out = np.eye(4)
    out[:3, :3] = m
    return out


def paper_curve_handle_grasp(theta: float, r_out: float) -> np.ndarray:
    """The paper's G = R(0, 0, theta) T(0, -R_o, 0) R(pi/2, 0, pi/2) G*, written independently;
    G* = Ry(pi/2) turns the paper's gripper (approach along x) into ours (approach along z)."""
    t = np.eye(4)
    t[1, 3] = -r_out
    r_pi = rot("z", np.pi / 2) @ rot("y", 0.0) @ rot("x", np.pi / 2)
    return rot("z", theta) @ t @ r_pi @ rot("y", np.pi / 2)


def random_pose(rng: np.random.Generator) -> np.ndarray:
    q, _ = np.linalg.qr(rng.normal(size=(3, 3)))
    q *= np.sign(np.linalg.det(q))
    m = np.eye(4)
    m[:3, :3], m[:3, 3] = q, rng.normal(size=3)
    return m


@settings(max_examples=40, deadline=None, derandomize=True)
@given(
    radian=st.floats(np.radians(20), np.radians(180)),
    r_in=st.floats(0.005, 0.15),
    gap=st.floats(0.0021, 0.05),  # r_out - r_in >= 2mm must survive rounding
    u=st.floats(-1, 1),
    seed=st.integers(0, 2**16),
)
def test_curve_handle_grasp_matches_the_paper(lib, radian, r_in, gap, u, seed) -> None:  # type: ignore[no-untyped-def]
    r_out = r_in + gap
    pose = random_pose(np.random.default_rng(seed))
    inst = lib["CurveHandle"].instantiate(pose=pose, radian=radian, r_in=r_in, r_out=r_out)
    lo, hi = inst.grasp_range("pull")["theta"]
    assert (lo, hi) == pytest.approx((-radian / 2, radian / 2))
    theta = u * radian / 2
    want = pose @ paper_curve_handle_grasp(theta, r_out)
    np.testing.assert_allclose(inst.grasp("pull", theta=theta), want, atol=1e-12)


def test_curve_handle_grasp_approaches_radially(lib) -> None:  # type: ignore[no-untyped-def]
    """Our gripper convention: +z approaches the ring's centre, +y closes along the ring axis."""
    g = lib["CurveHandle"].instantiate().grasp("pull", theta=0.3)
    inward = -g[:3, 3] / np.linalg.norm(g[:3, 3])
    np.testing.assert_allclose(g[:3, 2], inward, atol=1e-12)
    np.testing.assert_allclose(np.abs(g[:3, 1]), [0, 0, 1], atol=1e-12)
    door = lib["SunkenDoor"].instantiate()
    assert door.grasp("handle.pull")[2, 2] < -0.99  # into the door's front


def test_grasps_spread_over_the_range(lib) -> None:  # type: ignore[no-untyped-def]
    inst = lib["CurveHandle"].instantiate(radian=np.pi / 2)
    poses = inst.grasps("pull", n=5)
    assert poses.shape == (5, 4, 4)
    for pose, theta in zip(poses, np.linspace(-np.pi / 4, np.pi / 4, 5)):
        np.testing.assert_allclose(pose, inst.grasp("pull", theta=theta), atol=1e-12)


def test_door_force_is_the_velocity_of_the_grasp_point(lib) -> None:  # type: ignore[no-untyped-def]
    """The pull direction equals the finite-difference motion of the attached gripper."""
    pose = random_pose(np.random.default_rng(3))
    for side in ("left", "right"):
        door = lib["SunkenDoor"].instantiate(pose=pose, hinge_side=side, joints={"hinge": 0.4})
        grasp = door.grasp("handle.pull", theta=0.2)
        path = door.follow("open", grasp, to=0.4 + 1e-6, steps=2)
        velocity = (path[1, :3, 3] - path[0, :3, 3]) / 1e-6
        np.testing.assert_allclose(
            door.force("open", grasp), velocity / np.linalg.norm(velocity), atol=1e-5
        )
        np.testing.assert_allclose(door.force("close", grasp), -door.force("open", grasp))


def test_door_opens_towards_the_front(lib) -> None:  # type: ignore[no-untyped-def]
    for side in ("left", "right"):
        closed = lib["SunkenDoor"].instantiate(hinge_side=side)
        opened = lib["SunkenDoor"].instantiate(hinge_side=side, joints={"hinge": 0.5})
        assert opened.grasp("handle.pull")[2, 3] > closed.grasp("handle.pull")[2, 3] + 0.05


def test_follow_keeps_the_grasp_on_the_moving_link(lib) -> None:  # type: ignore[no-untyped-def]
    door = lib["SunkenDoor"].instantiate(joints={"hinge": 0.1})
    grasp = door.grasp("handle.pull")
    path = door.follow("open", grasp, to=1.5, steps=9)
    for k, q in enumerate(np.linspace(0.1, 1.5, 9)):
        moved = lib["SunkenDoor"].instantiate(joints={"hinge": q})
        np.testing.assert_allclose(path[k], moved.grasp("handle.pull"), atol=1e-12)


def test_handle_part_matches_the_handle_concept(lib) -> None:  # type: ignore[no-untyped-def]
    """The door's handle grasp is the handle's grasp placed by the part pose."""
    door = lib["SunkenDoor"].instantiate(**{"handle.r_out": 0.05})
    handle = lib["CurveHandle"].instantiate(r_out=0.05)
    p = door.params
    z = p["size"][2] / 2 - p["handle.r_in"] * np.cos(p["handle.radian"] / 2)
    place = np.eye(4)
    place[:3, 3] = [p["handle_at"][0], p["handle_at"][1], z]
    place = place @ rot("x", -np.pi / 2)
    np.testing.assert_allclose(
        door.grasp("handle.pull", theta=0.3), place @ handle.grasp("pull", theta=0.3), atol=1e-12
    )


@pytest.mark.parametrize(
    "kwargs, error, text",
    [
        ({"radian": 5.0}, eac.ParameterError, "outside its range"),
        ({"radian": float("nan")}, eac.ParameterError, "finite"),
        ({"r_in": 0.047}, eac.RequirementError, "the bar needs material"),
        ({"raidan": 1.0}, eac.UnknownNameError, "did you mean 'radian'"),
        ({"r_in": (0.01, 0.02)}, eac.ParameterError, "takes 1 value"),
        ({"pose": np.zeros((4, 4))}, eac.ParameterError, "rigid transform"),
        ({"radian": True}, eac.ParameterError, "not a bool"),
        ({"pose": np.diag([1.0, 1.0, -1.0, 1.0])}, eac.ParameterError, "mirror image"),
        ({"joints": {"hinge": 0.1}}, eac.UnknownNameError, "no moving joints"),
    ],
)
def test_bad_input_gives_typed_errors(lib, kwargs, error, text) -> None:  # type: ignore[no-untyped-def]
    with pytest.raises(error, match=text):
        lib["CurveHandle"].instantiate(**kwargs)


def test_bad_queries_give_typed_errors(lib) -> None:  # type: ignore[no-untyped-def]
    door = lib["SunkenDoor"].instantiate()
    with pytest.raises(eac.UnknownNameError, match="did you mean 'handle.pull'"):
        door.grasp("handle.pul")
    with pytest.raises(eac.ParameterError, match="outside the range"):
        door.grasp("handle.pull", theta=3.0)
    with pytest.raises(eac.ParameterError, match="outside its range"):
        lib["SunkenDoor"].instantiate(joints={"hinge": 3.0})
    with pytest.raises(eac.ParameterError, match="one of"):
        lib["SunkenDoor"].instantiate(hinge_side="top")
    with pytest.raises(eac.UnknownNameError):
        lib["Nope"]


def test_requirement_errors_say_which_values_break_what(lib) -> None:  # type: ignore[no-untyped-def]
    """The message names the requirement, its condition and file:line, and the values it reads."""
    with pytest.raises(eac.RequirementError) as err:
        lib["CurveHandle"].instantiate(r_in=0.047)
    text = str(err.value)
    assert "the bar needs material (r_out - r_in >= 2mm, handles.eac:" in text
    assert "r_in = 47mm" in text and "r_out = 48mm" in text
    assert "1 requirement:" in text


@pytest.mark.parametrize(
    "joints, text",
    [
        ([0.3], "mapping"),
        ({"hinge": "wide"}, "takes one number"),
        ({"hinge": True}, "takes one number"),
        ({"hinge": (0.1, 0.2)}, "takes one number"),
        ({"hinge": float("nan")}, "outside its range"),
    ],
)
def test_bad_joint_values_give_typed_errors(lib, joints, text) -> None:  # type: ignore[no-untyped-def]
    with pytest.raises(eac.ParameterError, match=text):
        lib["SunkenDoor"].instantiate(joints=joints)


def test_bad_counts_and_points_give_typed_errors(lib) -> None:  # type: ignore[no-untyped-def]
    door = lib["SunkenDoor"].instantiate(joints={"hinge": 0.4})
    g = door.grasp("handle.pull")
    for call, text in [
        (lambda: door.grasps("handle.pull", n=2.5), "whole number"),
        (lambda: door.grasps("handle.pull", n=0), "at least 1"),
        (lambda: door.sample_surface(-1), "at least 0"),
        (lambda: door.sample_surface("3"), "whole number"),
        (lambda: door.sample_surface(10, seed=0.5), "whole number"),
        (lambda: door.follow("open", g, to=1.0, steps=1), "at least 2"),
        (lambda: door.follow("open", g, to="far"), "takes one number"),
        (lambda: door.sdf([0.0, 0.0, 0.0]), "for one point use"),
        (lambda: door.sdf([["a", "b", "c"]]), "must be numbers"),
        (lambda: door.sdf([[0.0, 0.0, 0.0], [np.nan, 0.0, 0.0]]), "row 1"),
    ]:
        with pytest.raises(eac.ParameterError, match=text):
            call()
    assert door.sdf(np.zeros((0, 3))).shape == (0,)
    assert door.sample_surface(0).shape == (0, 3)


def test_follow_moves_the_joint_the_way_the_action_drives_it(lib) -> None:  # type: ignore[no-untyped-def]
    door = lib["SunkenDoor"].instantiate(joints={"hinge": 0.4})
    g = door.grasp("handle.pull")
    assert door.follow("close", g, to=0.1, steps=3).shape == (3, 4, 4)
    with pytest.raises(eac.ParameterError, match="cannot end at 0.1"):
        door.follow("open", g, to=0.1)
    with pytest.raises(eac.ParameterError, match="cannot end at 1"):
        door.follow("close", g, to=1.0)


def test_strict_requirements_are_strict(tmp_path) -> None:  # type: ignore[no-untyped-def]
    """`require a < b` rejects a == b at run time, as the checker does at the defaults."""
    src = tmp_path / "strict.eac"
    src.write_text(
        "concept S {\n    param a : length in [0mm, 10mm] = 1mm\n"
        '    param b : length in [0mm, 10mm] = 5mm\n    require a < b "a below b"\n}\n'
    )
    concept = eac.compile_paths([src])["S"]
    concept.instantiate(a=0.004, b=0.005)
    with pytest.raises(eac.RequirementError, match="a below b"):
        concept.instantiate(a=0.005, b=0.005)


def test_a_part_choice_bound_to_an_option_compiles(tmp_path, lib) -> None:  # type: ignore[no-untyped-def]
    """Binding a part's choice to a written-out option lowers (it crashed in CasADi once)."""
    src = tmp_path / "g.eac"
    src.write_text('use handles.{LeverHandle}\nconcept G { part h = LeverHandle(hand: "right") }\n')
    g = eac.compile_paths([src])["G"]
    assert "h.hand" not in [p.name for p in g.params]
    right = g.instantiate().grasp(next(iter(g.grasps)))
    left = lib["LeverHandle"].instantiate(hand="right").grasp(next(iter(g.grasps)).split(".", 1)[1])
    np.testing.assert_allclose(right, left, atol=1e-12)


VALVE = """use primitives.{Cylinder}

/// A valve wheel on a pipe, turned about its own axis (+z, out of the front).
concept Valve {
    param radius : length in [15mm, 38mm] = 30mm
    shape wheel = Cylinder(radius: radius, height: 20mm)
    /// Pinch the wheel from the front across its diameter.
    grasp grip = roty(180deg) width 2 * radius
    /// Open the valve: turn it counter-clockwise seen from the front.
    action open = turn toward (0, 0, 1) using grip
    /// Close it: turn it clockwise.
    action close = turn toward (0, 0, -1) using grip
}
"""


def test_a_turn_with_a_direction_is_a_twist_about_it(tmp_path) -> None:  # type: ignore[no-untyped-def]
    """`turn toward a` has no linear force: the hand turns about a (in the world), a pinch can
    do it, and verification checks the axis is a unit vector."""
    from grace_dsl.runtime.verify import verify_concept

    src = tmp_path / "valve.eac"
    src.write_text(VALVE)
    valve = eac.compile_paths([src])["Valve"]
    pose = random_pose(np.random.default_rng(3))
    inst = valve.instantiate(pose=pose)
    np.testing.assert_allclose(inst.twist("open"), pose[:3, 2], atol=1e-12)
    np.testing.assert_allclose(inst.twist("close"), -pose[:3, 2], atol=1e-12)
    with pytest.raises(eac.ParameterError, match="inst.twist"):
        inst.force("open", grasp=inst.grasp("grip"))
    (option,) = inst.rank("open")
    assert option.feasible and option.mode == "pinch"
    report = verify_concept(valve, draws=3, seed=0)
    assert report.failures == ()
    assert report.evaluated.get("unit_force", 0) > 0

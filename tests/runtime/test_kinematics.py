"""The Kinematics facade: poses agree with the instance API, Jacobians with central finite
differences (rotations differenced through scipy, independently of the compiled twist), at random
parameters, poses, joints and free grasp parameters."""

from __future__ import annotations

import numpy as np
import pytest
from scipy.spatial.transform import Rotation

import grace_dsl as eac
from grace_dsl.compiler.resolve import stdlib_dir
from grace_dsl.runtime.kinematics import Kinematics
from grace_dsl.runtime.verify import draw_params, random_pose

STEP = 1e-6


@pytest.fixture(scope="module")
def lib() -> eac.Library:
    files = ["doors.eac", "cabinets.eac", "knobs.eac"]
    return eac.compile_paths([stdlib_dir() / f for f in files])


def random_instance(concept: eac.Concept, seed: int) -> eac.Instance:
    """An instance at random valid parameters, pose and joint values (deterministic by seed)."""
    rng = np.random.default_rng(seed)
    for _ in range(200):
        try:
            inst = concept.instantiate(pose=random_pose(rng), **draw_params(concept, rng))
        except eac.RequirementError:
            continue
        joints = {}
        for name, (lo, hi) in inst.joint_limits().items():
            lo, hi = max(lo, -np.pi), min(hi, np.pi)  # continuous joints: one turn
            joints[name] = float(rng.uniform(lo, hi))
        return concept.instantiate(pose=inst.pose, joints=joints, **inst.params)
    raise AssertionError(f"no valid parameters for {concept.name}")


def numeric_twist(pose_of, x: np.ndarray) -> np.ndarray:  # type: ignore[no-untyped-def]
    """Central differences of a pose function: [dt/dx; w], w from the relative rotation."""
    cols = []
    for i in range(x.size):
        dx = np.zeros_like(x)
        dx[i] = STEP
        plus, minus = pose_of(x + dx), pose_of(x - dx)
        v = (plus[:3, 3] - minus[:3, 3]) / (2 * STEP)
        w = Rotation.from_matrix(plus[:3, :3] @ minus[:3, :3].T).as_rotvec() / (2 * STEP)
        cols.append(np.concatenate([v, w]))
    return np.array(cols).T.reshape(6, x.size)


CASES = [  # concept, grasp, link: a revolute door, a nested joint, drawers, knobs, no free
    # parameters, no joints
    ("SunkenDoor", "handle.pull", "leaf"),
    ("RoomDoor", "handle.hold", "handle.lever"),
    ("CabinetDrawer", "handle.pull", "drawer"),
    ("CabinetDrawer", "handle.hook", "base"),
    ("ChestOfDrawers", "handle2.pull", "drawer2"),
    ("RotaryDial", "grip", "dial"),
    ("RoundKnob", "pinch", "base"),
]


@pytest.mark.parametrize(("concept", "grasp", "link"), CASES)
@pytest.mark.parametrize("seed", [0, 1, 2])
def test_grasp_jacobian_matches_finite_differences(lib, concept, grasp, link, seed) -> None:  # type: ignore[no-untyped-def]
    inst = random_instance(lib[concept], seed)
    kin = Kinematics.of(inst)
    rng = np.random.default_rng(seed + 100)
    lo, hi, _ = kin.grasp_range(grasp)
    g = rng.uniform(lo, hi)
    nq = len(kin.joints)
    x = np.concatenate([inst.q, g])
    jac = kin.grasp_jacobian(grasp, inst.q, g)
    assert jac.shape == (6, nq + g.size)
    numeric = numeric_twist(lambda x: kin.grasp_pose(grasp, x[:nq], x[nq:]), x)
    np.testing.assert_allclose(jac, numeric, atol=2e-6)
    pose, jac2 = kin.grasp_pose_jacobian(grasp, inst.q, g)
    np.testing.assert_array_equal(jac, jac2)
    free = dict(zip(kin.free_parameters(grasp), g))
    if not inst.concept.grasps[grasp].get("symmetric"):
        np.testing.assert_allclose(pose, inst.grasp(grasp, **free), atol=1e-12)


@pytest.mark.parametrize(("concept", "grasp", "link"), CASES)
def test_link_jacobian_matches_finite_differences(lib, concept, grasp, link) -> None:  # type: ignore[no-untyped-def]
    inst = random_instance(lib[concept], 7)
    kin = Kinematics.of(inst)
    jac = kin.link_jacobian(link)
    numeric = numeric_twist(lambda q: kin.link_pose(link, q), inst.q)
    np.testing.assert_allclose(jac, numeric, atol=2e-6)
    np.testing.assert_allclose(kin.link_pose(link), inst.link_pose(link), atol=1e-12)


def test_revolute_jacobian_is_the_axis_and_its_moment(lib) -> None:  # type: ignore[no-untyped-def]
    """A closed-form check: a door leaf turns about its hinge axis a through o, so its twist
    column is [a x (t - o); a] (independent of finite differences)."""
    inst = random_instance(lib["SunkenDoor"], 3)
    kin = Kinematics.of(inst)
    axes = kin.joint_axes()
    a, o = axes.axes[0], axes.origins[0]
    t = kin.link_pose("leaf")[:3, 3]
    np.testing.assert_allclose(
        kin.link_jacobian("leaf")[:, 0], [*np.cross(a, t - o), *a], atol=1e-12
    )
    np.testing.assert_allclose(np.linalg.norm(axes.axes, axis=1), 1.0)
    assert not kin.link_jacobian("base").any()


def test_batches_agree_with_single_calls(lib) -> None:  # type: ignore[no-untyped-def]
    inst = random_instance(lib["RoomDoor"], 4)
    kin = Kinematics.of(inst)
    rng = np.random.default_rng(4)
    grasp = "handle.hold"
    lo, hi = kin.joint_limits()
    qs = rng.uniform(lo, hi, size=(5, lo.size))
    poses = kin.link_poses(qs)
    assert poses.shape == (5, len(kin.links), 4, 4)
    for k, q in enumerate(qs):
        np.testing.assert_allclose(poses[k], kin.link_poses(q), atol=1e-12)
        for i, link in enumerate(kin.links):
            np.testing.assert_allclose(poses[k, i], kin.link_pose(link, q), atol=1e-12)
    glo, ghi, _ = kin.grasp_range(grasp)
    gs = rng.uniform(glo, ghi, size=(5, glo.size))
    jacs = kin.grasp_jacobian(grasp, qs, gs)
    assert jacs.shape == (5, 6, lo.size + glo.size)
    for k in range(5):
        np.testing.assert_allclose(jacs[k], kin.grasp_jacobian(grasp, qs[k], gs[k]))
    np.testing.assert_allclose(
        kin.grasp_pose(grasp, qs, gs[1])[3], kin.grasp_pose(grasp, qs[3], gs[1])
    )
    axes = kin.joint_axes(qs)
    assert axes.axes.shape == axes.origins.shape == (5, lo.size, 3)
    np.testing.assert_allclose(axes.axes[2], kin.joint_axes(qs[2]).axes, atol=1e-12)


def test_a_single_configuration_of_a_one_joint_concept_stays_a_batch(lib) -> None:  # type: ignore[no-untyped-def]
    kin = Kinematics.of(lib["SunkenDoor"])  # one joint: q batch (1, 1) is also q's own shape
    assert kin.link_poses(np.array([[0.3]])).shape == (1, 2, 4, 4)
    assert kin.grasp_jacobian("handle.pull", [[0.3]], [[0.1]]).shape == (1, 6, 2)


def test_kinematics_of_a_concept_is_closed_at_defaults(lib) -> None:  # type: ignore[no-untyped-def]
    concept = lib["CabinetDrawer"]
    pose = random_pose(np.random.default_rng(5))
    kin = Kinematics.of(concept, pose)
    inst = concept.instantiate(pose=pose)
    np.testing.assert_allclose(kin.link_poses(), [inst.link_pose(n) for n in concept.links])
    np.testing.assert_allclose(kin.grasp_pose("handle.pull"), inst.grasp("handle.pull"))
    closed = Kinematics.of(concept)
    np.testing.assert_array_equal(closed.pose, np.eye(4))
    by_name = closed.grasp_pose("push_front", {"slide": 0.1}, {"s": 0.05})
    np.testing.assert_allclose(by_name, closed.grasp_pose("push_front", [0.1], [0.05]))


@pytest.mark.parametrize(
    ("call", "error", "words"),
    [
        (lambda k: k.link_pose("lef"), eac.UnknownNameError, "did you mean 'leaf'"),
        (lambda k: k.grasp_pose("pul"), eac.UnknownNameError, "no grasp 'pul'"),
        (lambda k: k.link_pose("leaf", [0.1, 0.2]), eac.ParameterError, "shape (1,) or (N, 1)"),
        (lambda k: k.link_pose("leaf", [np.nan]), eac.ParameterError, "finite"),
        (lambda k: k.link_pose("leaf", ["a"]), eac.ParameterError, "must be numbers"),
        (lambda k: k.link_pose("leaf", {"hindge": 1}), eac.UnknownNameError, "'hinge'"),
        (
            lambda k: k.grasp_pose("push_edge", 0.1, {"t": 0}),
            eac.UnknownNameError,
            "has no free parameter 't'; known: s",
        ),
        (
            lambda k: k.grasp_pose("push_edge", [[0.1]] * 2, [[0]] * 3),
            eac.ParameterError,
            "2 and 3",
        ),
        (lambda k: Kinematics.of(k.concept, np.ones((4, 4))), eac.ParameterError, "rigid"),
    ],
)
def test_bad_input_is_a_typed_error(lib, call, error, words) -> None:  # type: ignore[no-untyped-def]
    kin = Kinematics.of(lib["SunkenDoor"])
    with pytest.raises(error, match=None) as info:
        call(kin)
    assert words in str(info.value)


def test_twist_jacobian_of_a_closed_form_pose() -> None:
    """rotz(x) trans(a, 0, 0) with a = 2: the origin moves as a (-sin x, cos x, 0), the frame
    turns about z; y enters through trans(0, y, 0) only: linear (-sin x, cos x, 0)."""
    import casadi as ca

    from grace_dsl.compiler.functions import twist_jacobian

    x = ca.SX.sym("x", 2)
    c, s = ca.cos(x[0]), ca.sin(x[0])
    rot = ca.vertcat(ca.horzcat(c, -s, 0), ca.horzcat(s, c, 0), ca.horzcat(0, 0, 1))
    t = ca.mtimes(rot, ca.vertcat(2, x[1], 0))
    pose = ca.vertcat(ca.horzcat(rot, t), ca.horzcat(0, 0, 0, 1))
    fn = ca.Function("j", [x], [twist_jacobian(pose, x)])
    a, y = 0.7, 0.3
    expected = [
        [-2 * np.sin(a) - y * np.cos(a), -np.sin(a)],
        [2 * np.cos(a) - y * np.sin(a), np.cos(a)],
        [0, 0],
        [0, 0],
        [0, 0],
        [1, 0],
    ]
    np.testing.assert_allclose(fn([a, y]).full(), expected, atol=1e-15)


def test_native_and_casadi_jacobians_agree(lib) -> None:  # type: ignore[no-untyped-def]
    """The compiled grasp_jac kernel against CasADi's VM on the same serialized function."""
    import json

    import casadi as ca

    from grace_dsl.compiler import native

    if native.find_compiler() is None:
        pytest.skip("no C compiler: every function runs on CasADi's VM")
    concept = lib["RoomDoor"]
    inst = random_instance(concept, 9)
    compiled = concept.function("grasp_jac", "handle.hold")
    assert compiled.backend == "native"
    unit = concept._functions.unit  # the serialized function the kernel was generated from
    data = json.loads((unit.dir / "functions.json").read_text())
    key = concept.entry["functions"]["grasp_jac:handle.hold"]
    vm = native.CasadiEvaluator(ca.Function.deserialize(data[key]))
    g = np.array([0.01])
    for got, want in zip(compiled(inst.p, inst.q, g), vm(inst.p, inst.q, g)):
        np.testing.assert_allclose(got, want, rtol=1e-13, atol=1e-13)

"""URDF and MJCF exports: they load in Pinocchio and MuJoCo, and their link poses at random joint
values equal the runtime's link functions (times each link's frame offset) to 1e-6."""

from __future__ import annotations

import json
import math
from pathlib import Path

import mujoco
import numpy as np
import pinocchio as pin
import pytest

import grace_dsl as eac
from grace_dsl.cli.eacc import main
from grace_dsl.compiler.build import front_end
from grace_dsl.compiler.resolve import stdlib_dir
from grace_dsl.export import build_model, export_mjcf, export_urdf
from grace_dsl.export.common import quat_wxyz, rpy
from grace_dsl.export.model import ExportModel, Joint

HERE = Path(__file__).parent
TOL = 1e-6


@pytest.fixture(scope="module")
def concepts() -> dict[str, eac.Concept]:
    """Every concept of the standard library (primitives too: an instance of one is the
    primitive itself), and the test cabinet."""
    out = {}
    for lib in (eac.load_library(), eac.compile_paths([HERE / "cabinet.eac"])):
        out.update({n: lib[n] for n in lib})
    return out


def _concept_names() -> list[str]:
    """Every concept of the library and of the test file (front end only)."""
    prog, _, diags = front_end([stdlib_dir(), HERE / "cabinet.eac"])
    assert not diags, diags
    return sorted(prog.concepts)


NAMES = _concept_names()
PRIMITIVE_NAMES = {"Cuboid", "Cylinder", "Tube", "Ring", "RectRing", "Sphere", "Capsule"}
PRIMITIVE_NAMES |= {"Frustum", "TaperedCuboid", "SphericalCap", "Torus", "Prism"}


def test_every_library_concept_is_covered(concepts) -> None:  # type: ignore[no-untyped-def]
    assert set(concepts) == set(NAMES) and {"SunkenDoor", "Knob", "Cabinet"} <= set(NAMES)
    assert set(NAMES) >= PRIMITIVE_NAMES


@pytest.mark.parametrize("name", sorted(PRIMITIVE_NAMES))
def test_a_primitive_exports_as_one_geom_of_its_own_volume(
    concepts: dict[str, eac.Concept], name: str
) -> None:
    from grace_dsl.geometry import volume

    inst = concepts[name].instantiate()
    (link,) = build_model(inst).links
    (geom,) = link.geoms
    assert geom.primitive == name and dict(geom.params).keys() == inst.params.keys()
    assert geom.mesh.volume == pytest.approx(volume(name, inst.params), rel=0.02)
    assert link.inertial.mass > 0


def _random_pose(rng: np.random.Generator) -> np.ndarray:
    q, _ = np.linalg.qr(rng.normal(size=(3, 3)))
    pose = np.eye(4)
    pose[:3, :3] = q * np.sign(np.linalg.det(q))
    pose[:3, 3] = rng.uniform(-1, 1, 3)
    return pose


def _instance(concept: eac.Concept, seed: int) -> eac.Instance:
    return concept.instantiate(pose=_random_pose(np.random.default_rng(seed)))


def _random_joints(model: ExportModel, rng: np.random.Generator) -> dict[str, float]:
    return {
        j.source: rng.uniform(j.lo, j.hi) if j.lo is not None else rng.uniform(-7, 7)
        for j in model.joints
        if j.kind != "fixed"
    }


def _expected(inst: eac.Instance, model: ExportModel, values: dict[str, float]) -> dict:  # type: ignore[type-arg]
    """World pose of every exported link frame from the runtime: M L_k(p, q) offset_k."""
    q = np.array([values.get(n, 0.0) for n in inst.concept.moving_joints])  # absent copies: 0
    return {
        link.name: inst.pose @ inst.concept.function("link", link.source)(inst.p, q) @ link.offset
        for link in model.links
    }


def _pin_q(pmodel: pin.Model, joints: dict[str, Joint], values: dict[str, float]) -> np.ndarray:
    q = pin.neutral(pmodel)
    for jid in range(1, pmodel.njoints):
        j = joints[pmodel.names[jid]]
        i, v = pmodel.joints[jid].idx_q, values[j.source]
        if pmodel.joints[jid].nq == 2:  # continuous: cos, sin
            q[i : i + 2] = math.cos(v), math.sin(v)
        else:
            q[i] = v
    return q


@pytest.mark.parametrize("name", NAMES)
def test_urdf_loads_in_pinocchio_and_matches_the_runtime(concepts, name, tmp_path) -> None:  # type: ignore[no-untyped-def]
    inst = _instance(concepts[name], seed=len(name))
    path = tmp_path / f"{name}.urdf"
    export_urdf(inst, path)
    model = build_model(inst)
    pmodel = pin.buildModelFromUrdf(str(path))
    kind = pin.GeometryType.COLLISION
    geoms = pin.buildGeomFromUrdf(pmodel, str(path), kind, package_dirs=[str(tmp_path)])
    # the collision elements are the convex pieces (the whole pieces where a link has none)
    assert geoms.ngeoms == sum(len(link.collision or link.geoms) for link in model.links)
    data = pmodel.createData()
    joints = {j.name: j for j in model.joints}
    rng = np.random.default_rng(7)
    for _ in range(5):
        values = _random_joints(model, rng)
        pin.framesForwardKinematics(pmodel, data, _pin_q(pmodel, joints, values))
        for link, want in _expected(inst, model, values).items():
            got = data.oMf[pmodel.getFrameId(link)].homogeneous
            np.testing.assert_allclose(got, want, atol=TOL, err_msg=f"{name}.{link}")


def _mj_pose(data: mujoco.MjData, body: int) -> np.ndarray:
    out = np.eye(4)
    out[:3, :3] = data.xmat[body].reshape(3, 3)
    out[:3, 3] = data.xpos[body]
    return out


@pytest.mark.parametrize("name", NAMES)
def test_mjcf_loads_in_mujoco_and_matches_the_runtime(concepts, name, tmp_path) -> None:  # type: ignore[no-untyped-def]
    inst = _instance(concepts[name], seed=len(name) + 1)
    path = tmp_path / f"{name}.xml"
    export_mjcf(inst, path)
    model = build_model(inst)
    mj = mujoco.MjModel.from_xml_path(str(path))
    data = mujoco.MjData(mj)
    rng = np.random.default_rng(11)
    for _ in range(5):
        values = _random_joints(model, rng)
        for j in model.joints:
            if j.kind != "fixed":
                data.qpos[mj.jnt_qposadr[mj.joint(j.name).id]] = values[j.source]
        mujoco.mj_kinematics(mj, data)
        for link, want in _expected(inst, model, values).items():
            got = _mj_pose(data, mj.body(link).id)
            np.testing.assert_allclose(got, want, atol=TOL, err_msg=f"{name}.{link}")


def test_mjcf_keyframe_is_the_instance_state(concepts) -> None:  # type: ignore[no-untyped-def]
    concept = concepts["Cabinet"]
    joints = {"slide": 0.1, "hinge": 0.7, "flip": 0.3, "knob.spin": -2.0}
    inst = concept.instantiate(pose=_random_pose(np.random.default_rng(3)), joints=joints)
    mj = mujoco.MjModel.from_xml_string(export_mjcf(inst))  # no path: meshes inline
    data = mujoco.MjData(mj)
    mujoco.mj_resetDataKeyframe(mj, data, mj.key("instance").id)
    mujoco.mj_kinematics(mj, data)
    for link, want in _expected(inst, build_model(inst), joints).items():
        np.testing.assert_allclose(_mj_pose(data, mj.body(link).id), want, atol=TOL)


def test_joint_kinds_and_limits(concepts) -> None:  # type: ignore[no-untyped-def]
    model = build_model(concepts["Cabinet"].instantiate())
    kinds = {j.source: (j.kind, j.lo, j.hi) for j in model.joints}
    assert kinds == {
        "slide": ("prismatic", 0.0, pytest.approx(0.2)),
        "hinge": ("revolute", 0.0, pytest.approx(math.radians(100))),
        "mount": ("fixed", None, None),
        "flip": ("revolute", pytest.approx(-math.pi / 4), pytest.approx(math.pi / 4)),
        "knob.spin": ("continuous", None, None),
    }
    names = {link.source: link.name for link in model.links}
    assert names["knob.cap"] == "knob__cap"
    spin = next(j for j in model.joints if j.source == "knob.spin")
    assert (spin.damping, spin.friction) == (0.5, 0.1)


def test_geoms_native_meshes_union_and_difference(concepts, tmp_path) -> None:  # type: ignore[no-untyped-def]
    inst = concepts["Cabinet"].instantiate()
    model = build_model(inst)
    base = {g.name: g for g in model.root.geoms}
    assert set(base) == {"body", "a", "b", "holed", "ring"}  # a union becomes its operands
    holed = base["holed"]  # a 60 mm cube minus a 10 mm-radius cylinder through it
    assert holed.primitive == "mesh" and holed.mesh.is_watertight
    assert holed.mesh.volume == pytest.approx(0.06**3 - math.pi * 0.01**2 * 0.06, rel=2e-3)
    assert model.warnings == ()
    urdf = export_urdf(inst, tmp_path / "c.urdf")
    assert 'filename="c_meshes/ring.obj"' in urdf and (tmp_path / "c_meshes/ring.obj").is_file()
    assert 'filename="c_meshes/drawer' not in urdf  # drawer geoms are named by shape
    assert 'filename="c_meshes/rail.obj"' in urdf  # URDF has no capsule
    mjcf = export_mjcf(inst, tmp_path / "c.xml")
    assert 'type="capsule"' in mjcf and 'file="c_meshes/wedge.stl"' in mjcf  # a sector: mesh


def test_masses_follow_the_density(concepts) -> None:  # type: ignore[no-untyped-def]
    inst = concepts["SunkenDoor"].instantiate()
    leaf = next(link for link in build_model(inst).links if link.source == "leaf")
    size, rim, depth = np.array([0.5, 0.8, 0.025]), 0.04, 0.008
    frame = (size[0] * size[1] - (size[0] - 2 * rim) * (size[1] - 2 * rim)) * depth
    handle = 2 * math.pi / 3 / 2 * (0.048**2 - 0.040**2) * 0.012
    assert leaf.inertial.mass == pytest.approx(600 * (np.prod(size) + frame + handle), rel=1e-2)
    assert np.all(np.linalg.eigvalsh(leaf.inertial.inertia) > 0)
    base = build_model(inst).root
    assert base.geoms == () and base.inertial.mass == pytest.approx(0.01)


@pytest.mark.parametrize("seed", range(20))
def test_rotation_conversions(seed: int) -> None:
    rng = np.random.default_rng(seed)
    r = _random_pose(rng)[:3, :3] if seed else np.array([[0, 0, 1], [0, 1, 0], [-1, 0, 0.0]])
    roll, pitch, yaw = rpy(r)
    np.testing.assert_allclose(pin.rpy.rpyToMatrix(roll, pitch, yaw), r, atol=1e-12)
    w, x, y, z = quat_wxyz(r)
    np.testing.assert_allclose(pin.Quaternion(w, x, y, z).matrix(), r, atol=1e-12)


# ---- command line -------------------------------------------------------------------------------


def test_cli_exports_with_params_and_joints(tmp_path, capsys) -> None:  # type: ignore[no-untyped-def]
    params = tmp_path / "p.json"
    params.write_text(json.dumps({"size": [0.6, 0.9, 0.03], "hinge_side": "left"}))
    out = tmp_path / "door.xml"
    argv = ["export", "SunkenDoor", "--mjcf", str(out), "--params-json", str(params)]
    argv += ["--param", "hinge_side=right", "--param", "rim=0.05", "--joint", "hinge=0.5", "--json"]
    assert main(argv) == 0
    summary = json.loads(capsys.readouterr().out)
    assert summary["joints"][0]["value"] == 0.5
    meshes = [str(tmp_path / "door_meshes" / f) for f in ("frame.stl", "handle__bar.stl")]
    assert summary["meshes"] == meshes
    mj = mujoco.MjModel.from_xml_path(str(out))
    assert mj.geom("panel").size.tolist() == pytest.approx([0.3, 0.45, 0.015])
    assert main(["export", "CurveHandle", "--urdf", str(tmp_path / "h.urdf")]) == 0
    assert "wrote" in capsys.readouterr().out


@pytest.mark.parametrize(
    "extra, message",
    [
        (["--joint", "hing=1"], "no moving joint 'hing'; did you mean 'hinge'?"),
        (["--param", "siz=1"], "no parameter 'siz'; did you mean 'size'?"),
        (["--param", "size=a"], "size takes 3 number(s)"),
        (["--param", "rim"], "--param expects NAME=VALUE"),
        (["--joint", "hinge=2"], "outside its range"),
        (["--params-json", "/nonexistent.json"], "cannot read the instance file"),
    ],
)
def test_cli_bad_input_is_one_message(tmp_path, capsys, extra, message) -> None:  # type: ignore[no-untyped-def]
    assert main(["export", "SunkenDoor", "--urdf", str(tmp_path / "d.urdf"), *extra]) == 1
    err = capsys.readouterr().err
    assert message in err and "Traceback" not in err


def test_cli_unknown_concept(tmp_path, capsys) -> None:  # type: ignore[no-untyped-def]
    assert main(["export", "Sunken", "--urdf", str(tmp_path / "d.urdf")]) == 1
    assert "did you mean 'SunkenDoor'" in capsys.readouterr().err

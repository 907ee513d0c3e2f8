"""The instance on the command line: ``--pose``, the instance file (``--instance-json``, alias
``--params-json``), the material options and output paths of ``eacc export``."""

from __future__ import annotations

import argparse
import json
import math
from pathlib import Path

import mujoco
import numpy as np
import pinocchio as pin
import pytest

import grace_dsl as eac
from grace_dsl.cli.eacc import main
from grace_dsl.cli.export_cmd import add_export_arguments
from grace_dsl.cli.instance_args import instance_from_args, parse_pose
from grace_dsl.export import build_model, write_mjcf, write_urdf
from grace_dsl.export.common import ExportPathError
from grace_dsl.runtime.shapes import ShapeTree
from tests.export.test_export import _mj_pose, _pin_q

HERE = Path(__file__).parent
CABINET = HERE / "cabinet.eac"
TOL = 1e-6
JOINTS = {"slide": 0.12, "hinge": 0.8, "flip": -0.3, "knob.spin": 2.5}
XYZ, RPY = (0.4, -1.2, 0.7), (0.3, -1.1, 2.4)


@pytest.fixture(scope="module")
def cabinet() -> eac.Concept:
    return eac.compile_paths([CABINET])["Cabinet"]


def _matrix(xyz: tuple[float, ...], rpy: tuple[float, ...]) -> np.ndarray:
    """Pinocchio's (URDF's) roll-pitch-yaw: an independent construction of the pose."""
    pose = np.eye(4)
    pose[:3, :3] = pin.rpy.rpyToMatrix(*rpy)
    pose[:3, 3] = xyz
    return pose


def _csv(values: np.ndarray | tuple[float, ...]) -> str:
    return ",".join(repr(float(v)) for v in np.ravel(values))


def test_rpy_is_the_language_rpy(tmp_path: Path) -> None:
    """A shape placed with the language's trans * rpy sits where --pose x,y,z,r,p,y says."""
    src = tmp_path / "probe.eac"
    src.write_text(
        "use primitives.{Cuboid}\n"
        "concept Probe {\n"
        "    shape s = Cuboid(size: (10mm, 10mm, 10mm))\n"
        "        at trans(400mm, -1200mm, 700mm) * rpy(20deg, -65deg, 130deg)\n"
        "}\n"
    )
    inst = eac.compile_paths([src])["Probe"].instantiate()
    placed = ShapeTree(inst).placement("s")
    given = parse_pose(_csv((*XYZ, *np.radians([20, -65, 130]))))
    np.testing.assert_allclose(given, placed, atol=1e-12)


POSES = {
    "xyz": (_csv(XYZ), _matrix(XYZ, (0, 0, 0))),
    "xyz-rpy": (_csv((*XYZ, *RPY)), _matrix(XYZ, RPY)),
    "matrix": (_csv(_matrix(XYZ, RPY)), _matrix(XYZ, RPY)),
}


def _cli_args(cabinet_out: Path, fmt: str, pose: str) -> list[str]:
    args = ["export", "Cabinet", str(CABINET), f"--{fmt}", str(cabinet_out), f"--pose={pose}"]
    return args + [a for k, v in JOINTS.items() for a in ("--joint", f"{k}={v}")]


def _expected(cabinet: eac.Concept, pose: np.ndarray) -> dict[str, np.ndarray]:
    """World pose of each exported link frame: the runtime's link pose times its offset."""
    inst = cabinet.instantiate(pose=pose, joints=JOINTS)
    return {k.name: inst.link_pose(k.source) @ k.offset for k in build_model(inst).links}


@pytest.mark.parametrize("form", sorted(POSES))
def test_pose_on_the_command_line_places_the_urdf(cabinet, tmp_path, form) -> None:
    text, pose = POSES[form]
    path = tmp_path / "c.urdf"
    assert main(_cli_args(path, "urdf", text)) == 0
    pmodel = pin.buildModelFromUrdf(str(path))
    data = pmodel.createData()
    joints = {j.name: j for j in build_model(cabinet.instantiate()).joints}
    pin.framesForwardKinematics(pmodel, data, _pin_q(pmodel, joints, JOINTS))
    for link, want in _expected(cabinet, pose).items():
        got = data.oMf[pmodel.getFrameId(link)].homogeneous
        np.testing.assert_allclose(got, want, atol=TOL, err_msg=link)


@pytest.mark.parametrize("form", sorted(POSES))
def test_pose_on_the_command_line_places_the_mjcf(cabinet, tmp_path, form) -> None:
    text, pose = POSES[form]
    path = tmp_path / "c.xml"
    assert main(_cli_args(path, "mjcf", text)) == 0
    mj = mujoco.MjModel.from_xml_path(str(path))
    data = mujoco.MjData(mj)
    mujoco.mj_resetDataKeyframe(mj, data, mj.key("instance").id)  # the joint values
    mujoco.mj_kinematics(mj, data)
    for link, want in _expected(cabinet, pose).items():
        np.testing.assert_allclose(_mj_pose(data, mj.body(link).id), want, atol=TOL, err_msg=link)


# ---- the instance file ---------------------------------------------------------------------------


def _parse(argv: list[str]) -> argparse.Namespace:
    p = argparse.ArgumentParser()
    add_export_arguments(p)
    return p.parse_args(["Cabinet", str(CABINET), "--urdf", "x.urdf", *argv])


def _file(tmp_path: Path, data: object) -> str:
    path = tmp_path / "instance.json"
    path.write_text(json.dumps(data))
    return str(path)


@pytest.mark.parametrize("option", ["--instance-json", "--params-json"])
def test_structured_file_sets_params_joints_and_pose(cabinet, tmp_path, option) -> None:
    pose = _matrix(XYZ, RPY)
    data = {"params": {"size": [0.5, 0.4, 0.3]}, "joints": JOINTS, "pose": pose.tolist()}
    lib = {"Cabinet": cabinet}
    inst = instance_from_args(_parse([option, _file(tmp_path, data)]), lib)
    assert inst.params["size"] == pytest.approx((0.5, 0.4, 0.3))
    assert dict(zip(inst.concept.moving_joints, inst.q)) == pytest.approx(JOINTS)
    np.testing.assert_allclose(inst.pose, pose, atol=1e-15)


def test_command_line_overrides_the_file(cabinet, tmp_path) -> None:
    data = {"params": {"size": [0.5, 0.4, 0.3], "travel": 0.1}, "joints": JOINTS, "pose": [1, 2, 3]}
    argv = ["--instance-json", _file(tmp_path, data), "--param", "travel=0.25"]
    argv += ["--joint", "hinge=0.1", "--pose=0,0,1,0,0,1.5"]
    inst = instance_from_args(_parse(argv), {"Cabinet": cabinet})
    assert inst.params["size"] == pytest.approx((0.5, 0.4, 0.3))  # from the file
    assert inst.params["travel"] == pytest.approx(0.25)  # the command line's
    q = dict(zip(inst.concept.moving_joints, inst.q))
    assert q == pytest.approx({**JOINTS, "hinge": 0.1})
    np.testing.assert_allclose(inst.pose, _matrix((0, 0, 1), (0, 0, 1.5)), atol=1e-15)


def test_flat_file_is_parameters_and_rpy_pose_in_the_file(cabinet, tmp_path) -> None:
    flat = instance_from_args(
        _parse(["--instance-json", _file(tmp_path, {"travel": 0.15})]), {"Cabinet": cabinet}
    )
    assert flat.params["travel"] == pytest.approx(0.15) and not flat.q.any()
    np.testing.assert_array_equal(flat.pose, np.eye(4))
    six = instance_from_args(
        _parse(["--instance-json", _file(tmp_path, {"pose": [*XYZ, *RPY]})]), {"Cabinet": cabinet}
    )
    np.testing.assert_allclose(six.pose, _matrix(XYZ, RPY), atol=1e-15)


NOT_RIGID = (np.diag([1.0, 2.0, 1.0, 1.0])).tolist()
MIRROR = (np.diag([1.0, 1.0, -1.0, 1.0])).tolist()


@pytest.mark.parametrize(
    ("data", "message"),
    [
        ({"joints": {"hinge": 0.2}, "size": [1, 1, 1]}, "unknown key(s) 'size'"),
        ({"params": [0.5]}, '"params" must be an object'),
        ({"joints": {"hinge": "open"}}, "joint hinge takes a number"),
        ({"joints": {"hinge": True}}, "joint hinge takes a number"),
        ({"joints": {"hing": 0.2}}, "did you mean 'hinge'"),
        ({"joints": {"hinge": 3.0}}, "outside its range"),
        ({"params": {"travel": "far"}}, "travel"),
        ({"pose": [1, 2]}, "takes 3 numbers (x,y,z), 6"),
        ({"pose": "1,2,3"}, '"pose" must be a list of 3, 6'),
        ({"pose": [[1, 0, 0], [0, 1, 0]]}, "4 rows of 4 numbers"),
        ({"pose": NOT_RIGID}, "not a rigid transform"),
        ({"pose": MIRROR}, "determinant +1"),
        ([1, 2, 3], "must hold a JSON object"),
    ],
)
def test_bad_instance_file_is_one_message(tmp_path, capsys, data, message) -> None:
    out = tmp_path / "c.urdf"
    argv = ["export", "Cabinet", str(CABINET), "--urdf", str(out)]
    assert main([*argv, "--instance-json", _file(tmp_path, data)]) == 1
    err = capsys.readouterr().err
    assert message in err and err.count("\n") == 1 and err.startswith("eacc: ")
    assert "Traceback" not in err and not out.exists()


def test_unreadable_instance_file(tmp_path, capsys) -> None:
    path = tmp_path / "bad.json"
    path.write_text("{not json")
    argv = ["export", "Cabinet", str(CABINET), "--urdf", str(tmp_path / "c.urdf")]
    assert main([*argv, "--params-json", str(path)]) == 1
    err = capsys.readouterr().err
    assert f"cannot read the instance file {path}" in err and err.count("\n") == 1


@pytest.mark.parametrize(
    ("pose", "message"),
    [
        ("1,2", "takes 3 numbers (x,y,z), 6 (x,y,z,roll,pitch,yaw in m and rad) or 16"),
        ("1,2,x", "--pose takes numbers separated by commas"),
        ("1,2,nan", "every number must be finite"),
        (_csv(np.diag([1.0, 1.0, 1.1, 1.0])), "not a rigid transform"),
        (_csv(np.diag([-1.0, 1.0, 1.0, 1.0])), "determinant +1"),
        (_csv(np.eye(4) + np.eye(4, k=-3)), "last row 0 0 0 1"),
    ],
)
def test_bad_pose_is_one_message(tmp_path, capsys, pose, message) -> None:
    argv = ["export", "Cabinet", str(CABINET), "--mjcf", str(tmp_path / "c.xml")]
    assert main([*argv, f"--pose={pose}"]) == 1
    err = capsys.readouterr().err
    assert message in err and err.count("\n") == 1 and "Traceback" not in err


# ---- material and output paths -------------------------------------------------------------------


def _masses(argv: list[str], capsys: pytest.CaptureFixture[str]) -> dict[str, float]:
    assert main(argv + ["--json"]) == 0
    return json.loads(capsys.readouterr().out)["masses"]


def test_density_and_wall_options_scale_the_masses(tmp_path, capsys) -> None:
    argv = ["export", "Refrigerator", "--mjcf", str(tmp_path / "f.xml")]
    base = _masses(argv, capsys)
    heavy = _masses([*argv, "--density", "1200"], capsys)
    thin = _masses([*argv, "--wall", "0.009"], capsys)
    assert heavy == pytest.approx({k: 2 * v for k, v in base.items()}, rel=1e-9)
    # the carcass is hollow at 18 mm, so its mass is proportional to the wall
    assert thin["base"] == pytest.approx(base["base"] / 2, rel=1e-9)
    mj = mujoco.MjModel.from_xml_path(str(tmp_path / "f.xml"))  # the last file: --wall 0.009
    assert mj.body_mass[mj.body("base").id] == pytest.approx(thin["base"], rel=1e-9)


@pytest.mark.parametrize(
    ("extra", "message"),
    [
        (["--density", "0"], "--density takes a positive number in kg/m^3, not '0'"),
        (["--density", "wood"], "--density takes a positive number"),
        (["--wall", "-0.01"], "--wall takes a positive number in m, not '-0.01'"),
        (["--wall", "inf"], "--wall takes a positive number"),
    ],
)
def test_bad_material_is_one_message(tmp_path, capsys, extra, message) -> None:
    assert main(["export", "Refrigerator", "--urdf", str(tmp_path / "f.urdf"), *extra]) == 1
    err = capsys.readouterr().err
    assert message in err and err.count("\n") == 1


@pytest.mark.parametrize("fmt", ["--obj", "--stl", "--glb", "--urdf", "--mjcf"])
@pytest.mark.parametrize("trailing", ["", "/"])
def test_a_directory_is_not_an_output_file(tmp_path, capsys, fmt, trailing) -> None:
    target = tmp_path / "out"
    target.mkdir()
    assert main(["export", "SunkenDoor", fmt, f"{target}{trailing}"]) == 1
    err = capsys.readouterr().err
    assert f"{target}{trailing} is a directory: give a file name, e.g. {target}/model." in err
    assert (
        err.count("\n") == 1
        and not any(target.iterdir())
        and not any(p for p in tmp_path.iterdir() if p.name != "out")
    )


def test_a_new_path_with_a_trailing_slash_is_a_directory(tmp_path, capsys) -> None:
    target = f"{tmp_path}/new/"
    assert main(["export", "SunkenDoor", "--obj", target]) == 1
    assert "is a directory" in capsys.readouterr().err and not (tmp_path / "new").exists()


def test_writers_refuse_a_directory(tmp_path) -> None:
    model = build_model(eac.load_library()["SunkenDoor"].instantiate())
    for write in (write_urdf, write_mjcf):
        with pytest.raises(ExportPathError, match="is a directory"):
            write(model, tmp_path)
    assert isinstance(ExportPathError("x"), eac.GraceError)


def test_rpy_matrix_is_a_rotation() -> None:
    pose = parse_pose("0,0,0,0.1,0.2,0.3")
    assert np.linalg.det(pose[:3, :3]) == pytest.approx(1.0)
    assert math.isclose(pose[2, 0], -math.sin(0.2))

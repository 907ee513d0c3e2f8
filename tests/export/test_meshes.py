"""Mesh exports (OBJ, STL, GLB): written, loaded back with trimesh, they have the volume and
bounds of ``inst.mesh()`` / ``inst.link_mesh(name)``."""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest
import trimesh

import grace_dsl as eac
from grace_dsl.cli.eacc import main
from grace_dsl.export.meshes import MeshExportError, write_instance_mesh
from grace_dsl.render import style

HERE = Path(__file__).parent


@pytest.fixture(scope="module")
def cabinet() -> eac.Instance:
    lib = eac.compile_paths([HERE / "cabinet.eac"])
    pose = np.eye(4)
    pose[:3, :3] = trimesh.transformations.rotation_matrix(0.7, [1, 2, 3])[:3, :3]
    pose[:3, 3] = (0.2, -0.4, 1.1)
    return lib["Cabinet"].instantiate(pose=pose, joints={"slide": 0.1, "hinge": 0.5})


def _load(path: Path) -> trimesh.Trimesh:
    loaded = trimesh.load(path, process=False)
    if isinstance(loaded, trimesh.Scene):
        loaded = loaded.to_geometry()
    assert isinstance(loaded, trimesh.Trimesh)
    return loaded


@pytest.mark.parametrize("fmt", ["obj", "stl", "glb"])
@pytest.mark.parametrize("link", [None, "drawer", "knob.cap"])
def test_round_trip(cabinet, tmp_path, fmt, link) -> None:
    path = tmp_path / f"cabinet.{fmt}"
    write_instance_mesh(cabinet, path, link=link)
    back = _load(path)
    expected = cabinet.mesh() if link is None else cabinet.link_mesh(link)
    rel = 1e-9 if fmt == "obj" else 1e-5  # STL and GLB store float32
    if fmt == "glb" and link is None:  # the links apart: their union's faces and volume differ
        links = [cabinet.link_mesh(n) for n in cabinet.concept.links]
        assert back.volume == pytest.approx(sum(m.volume for m in links), rel=rel)
        assert len(back.faces) == sum(len(m.faces) for m in links)
        return
    assert back.volume == pytest.approx(expected.volume, rel=rel)
    np.testing.assert_allclose(back.bounds, expected.bounds, atol=1e-6)
    assert len(back.faces) == len(expected.faces)


def test_glb_keeps_links_apart_in_their_colours(cabinet, tmp_path) -> None:
    path = tmp_path / "cabinet.glb"
    write_instance_mesh(cabinet, path)
    scene = trimesh.load(path)
    assert isinstance(scene, trimesh.Scene)
    links = list(cabinet.concept.links)
    assert set(scene.geometry) == {n for n in links if len(cabinet.link_mesh(n).faces)}
    for name, geom in scene.geometry.items():
        colour = np.asarray(geom.visual.material.baseColorFactor[:3]) / 255
        np.testing.assert_allclose(colour, style.link_color(links.index(name)), atol=1 / 255)
        assert geom.volume == pytest.approx(cabinet.link_mesh(name).volume, rel=1e-5)


def test_errors(cabinet, tmp_path) -> None:
    with pytest.raises(MeshExportError, match="obj, stl, glb"):
        write_instance_mesh(cabinet, tmp_path / "x.ply")
    with pytest.raises(eac.UnknownNameError, match="did you mean 'drawer'"):
        write_instance_mesh(cabinet, tmp_path / "x.obj", link="drawr")


def test_cli_mesh_export(tmp_path, capsys) -> None:
    out = tmp_path / "door.stl"
    args = ["export", "SunkenDoor", "--stl", str(out), "--link", "leaf", "--joint", "hinge=0.3"]
    assert main([*args, "--json"]) == 0
    summary = json.loads(capsys.readouterr().out)
    door = eac.load_library()["SunkenDoor"].instantiate(joints={"hinge": 0.3})
    expected = door.link_mesh("leaf")
    assert summary["link"] == "leaf" and summary["faces"] == len(expected.faces)
    assert summary["volume"] == pytest.approx(expected.volume)
    assert _load(out).volume == pytest.approx(expected.volume, rel=1e-5)  # float32


@pytest.mark.parametrize(
    ("extra", "message"),
    [
        (["--urdf", "x.urdf", "--link", "leaf"], "--link picks one link of a mesh file"),
        (["--obj", "x.obj", "--link", "base"], "link base has no shapes"),
        (["--obj", "x.obj", "--link", "lef"], "did you mean 'leaf'"),
    ],
)
def test_cli_mesh_errors(tmp_path, capsys, monkeypatch, extra, message) -> None:
    monkeypatch.chdir(tmp_path)
    assert main(["export", "SunkenDoor", *extra]) == 1
    err = capsys.readouterr().err
    assert message in err and "Traceback" not in err

"""``eacc show`` and ``eacc gallery`` from the command line."""

from __future__ import annotations

import json
import os
import subprocess
import sys

import numpy as np
import pytest
from PIL import Image

import grace_dsl as eac
from grace_dsl.cli.eacc import main
from grace_dsl.cli.show_cmd import gallery_jobs, image_size
from grace_dsl.geometry import PRIMITIVES
from tests.render.conftest import TOYBOX, needs_gl


@pytest.mark.slow
@needs_gl
def test_show_writes_png_and_html(tmp_path, capsys) -> None:
    png, page = tmp_path / "box.png", tmp_path / "box.html"
    code = main(
        [
            "show", "ToyBox", str(TOYBOX), "--png", str(png), "--html", str(page),
            "--param", "size=0.5,0.3,0.3", "--joint", "hinge=0.4", "--grasps", "2",
            "--size", "320x200", "--json",
        ]
    )  # fmt: skip
    assert code == 0
    out = json.loads(capsys.readouterr().out)
    assert out["png"] == str(png) and out["html"] == str(page)
    assert out["grasp_frames"] == {"pull.hold": 2, "pull.top": 1, "edge": 1}
    assert {f["action"] for f in out["forces"]} == {
        "pull.pull_out",
        "pull.spin",
        "open_lid",
        "open_drawer",
    }
    assert Image.open(png).size == (320, 200)
    assert "ToyBox" in page.read_text() and "hinge = 0.4" in page.read_text()


def test_show_without_outputs_reports_the_scene(capsys) -> None:
    assert main(["show", "Pull", str(TOYBOX)]) == 0
    text = capsys.readouterr().out
    assert "Pull: 2 links, 4 grasp frames, 2 forces, 1 joint axis" in text


def test_show_counts_links_without_shapes(capsys, lib) -> None:  # type: ignore[no-untyped-def]
    """SunkenDoor's base has no shapes: it is still a link, and the report says so."""
    door = lib["SunkenDoor"]
    assert len(door.links) == 2
    assert main(["show", "SunkenDoor", "--grasps", "1"]) == 0
    out = capsys.readouterr().out
    assert out.startswith("SunkenDoor: 2 links (1 with shapes), ") and "1 joint axis" in out
    assert main(["show", "Torus"]) == 0
    assert "Torus: 1 link, 0 grasp frames, 0 forces, 0 joint axes" in capsys.readouterr().out


def test_show_takes_the_pose(capsys) -> None:
    """``--pose`` moves everything the scene shows: forces' points by the pose, directions by its
    rotation (x, y, z and roll, pitch, yaw: Rz(yaw) Ry(pitch) Rx(roll))."""
    assert main(["show", "Pull", str(TOYBOX), "--json"]) == 0
    plain = json.loads(capsys.readouterr().out)
    assert (
        main(["show", "Pull", str(TOYBOX), "--json", "--pose=0.5,-1,2,0,0,1.5707963267948966"]) == 0
    )
    moved = json.loads(capsys.readouterr().out)
    turn = np.array([[0.0, -1, 0], [1, 0, 0], [0, 0, 1]])  # 90 deg about z
    assert len(plain["forces"]) == len(moved["forces"]) > 0
    for a, b in zip(plain["forces"], moved["forces"]):
        np.testing.assert_allclose(b["at"], turn @ a["at"] + [0.5, -1, 2], atol=1e-9)
        np.testing.assert_allclose(b["direction"], turn @ a["direction"], atol=1e-9)


@pytest.mark.parametrize(
    ("extra", "message"),
    [
        (["--size", "big"], "--size takes WIDTHxHEIGHT"),
        (["--joint", "hinge=7"], "outside its range"),
        (["--joint", "hnge=0.1"], "did you mean 'hinge'"),
        (["--grasps", "-1"], "grasps must be 0 or more"),
        (["--param", "size=1,2"], "size"),
        (["--pose", "1,2,3,4"], "--pose takes 3 numbers"),
        (["--pose=1,0,0,0,0,1,0,0,0,0,1,0,0,0,0,2"], "not a rigid transform"),
    ],
)
def test_show_bad_input_is_one_message(extra, message, capsys) -> None:
    assert main(["show", "ToyBox", str(TOYBOX), *extra]) == 1
    err = capsys.readouterr().err
    assert message in err and err.count("\n") == 1 and "Traceback" not in err


@needs_gl
def test_show_draws_a_primitive_concept(tmp_path, capsys) -> None:
    """A primitive concept's instance is the primitive: the picture is not blank."""
    png = tmp_path / "torus.png"
    assert main(["show", "Torus", "--png", str(png), "--size", "160x120"]) == 0
    pixels = np.asarray(Image.open(png).convert("RGB")).reshape(-1, 3).astype(int)
    background = pixels[0]
    assert np.mean(np.abs(pixels - background).sum(axis=1) > 30) > 0.02  # the ring's pixels


def test_image_size() -> None:
    assert image_size("640x480") == (640, 480)
    assert image_size("64X48") == (64, 48)


def test_gallery_covers_every_concept_and_registry_primitive(tmp_path) -> None:
    lib = eac.compile_paths([TOYBOX])
    jobs = gallery_jobs(lib, tmp_path)
    pics = {p.name: p for p, _ in jobs}
    concepts = [n for n in lib if lib[n].entry["kind"] == "concept"]
    assert set(pics) == set(concepts) | set(PRIMITIVES)
    assert pics["ToyBox"].path == tmp_path / "ToyBox.png"
    for name in PRIMITIVES:
        assert pics[name].path == tmp_path / "primitives" / f"{name}.png"


@needs_gl
def test_gallery_draws_small_pictures(tmp_path, capsys) -> None:
    args = ["gallery", str(TOYBOX), "-o", str(tmp_path), "--only", "ToyBox", "--only", "Capsule"]
    assert main([*args, "--json"]) == 0
    out = json.loads(capsys.readouterr().out)
    assert [p["name"] for p in out["pictures"]] == ["ToyBox", "Capsule"] and not out["failed"]
    for path in (tmp_path / "ToyBox.png", tmp_path / "primitives" / "Capsule.png"):
        img = Image.open(path)
        assert img.size == (640, 480) and path.stat().st_size < 100_000
        assert len(np.unique(np.asarray(img.convert("RGB")).reshape(-1, 3), axis=0)) > 50


def test_gallery_unknown_name(tmp_path, capsys) -> None:
    assert main(["gallery", str(TOYBOX), "-o", str(tmp_path), "--only", "ToyBx"]) == 1
    assert "did you mean 'ToyBox'" in capsys.readouterr().err


def test_show_png_without_a_gl_backend_is_one_message(tmp_path) -> None:
    """A fresh process whose MUJOCO_GL names no backend: exit 1 and what to install."""
    env = {**os.environ, "MUJOCO_GL": "none-such"}
    png = tmp_path / "x.png"
    cmd = [
        sys.executable,
        "-m",
        "grace_dsl.cli.eacc",
        "show",
        "Pull",
        str(TOYBOX),
        "--png",
        str(png),
    ]
    done = subprocess.run(cmd, env=env, capture_output=True, text=True, timeout=300)
    assert done.returncode == 1 and not png.exists()
    assert "MUJOCO_GL=none-such" in done.stderr and "libosmesa6" in done.stderr
    assert "Traceback" not in done.stderr

"""MuJoCo pictures: not blank, the frame and force colours where the camera model says they are."""

from __future__ import annotations

import numpy as np
import pytest
from PIL import Image

from grace_dsl.export import build_model
from grace_dsl.render import describe, primitive_scene
from grace_dsl.render.camera import frame_scene
from grace_dsl.render.png import RenderError, render_image, write_png
from tests.render.conftest import needs_gl, random_pose

pytestmark = needs_gl

W, H = 400, 300


def _mask(img: np.ndarray, colour: str) -> np.ndarray:
    r, g, b = (img[..., k].astype(int) for k in range(3))
    return {
        "red": (r > 150) & (g < 90) & (b < 90),
        "green": (g > 130) & (r < 110) & (b < 110),
        "blue": (b > 150) & (r < 100) & (g < 130),
        "magenta": (r > 150) & (b > 150) & (g < 120),
    }[colour]


def _pixel(scene, point) -> tuple[int, int]:
    """Where the pinhole model of the framing view puts a world point (column, row)."""
    view = frame_scene(scene, W / H)
    right, up, back = view.basis()
    rel = np.asarray(point) - np.array(view.eye)
    depth = -(rel @ back)
    t = np.tan(np.radians(view.fovy) / 2)
    x, y = (rel @ right) / depth / (t * W / H), (rel @ up) / depth / t
    return int(round(W / 2 + x * W / 2)), int(round(H / 2 - y * H / 2))


@pytest.fixture(scope="module")
def toybox(toy):
    pose = np.eye(4)
    pose[:3, 3] = (0.3, -0.2, 1.0)
    inst = toy["ToyBox"].instantiate(pose=pose, joints={"hinge": 0.6, "slide": 0.1})
    scene = describe(inst)
    return scene, render_image(scene, W, H, build_model(inst))


def test_picture_is_not_blank_and_shows_the_axis_colours(toybox) -> None:
    _, img = toybox
    assert img.shape == (H, W, 3) and img.dtype == np.uint8
    assert len(np.unique(img.reshape(-1, 3), axis=0)) > 300
    for colour in ("red", "green", "blue", "magenta"):
        assert _mask(img, colour).sum() > 15, colour
    corner = img[:5, :5].reshape(-1, 3).mean(axis=0)  # the neutral background
    assert np.all(np.abs(corner - 0.94 * 255) < 12)


def test_arrows_are_where_the_camera_model_puts_them(toybox) -> None:
    scene, img = toybox
    magenta = _mask(img, "magenta")
    segs = {s.label: s for s in scene.segments()}
    # points on two arrows that nothing hides (the lid's starts inside the pull's bar)
    for label, t in [
        ("open_drawer @ edge", 0.3),
        ("open_drawer @ edge", 0.7),
        ("pull.pull_out @ pull.hold", 0.5),
        ("pull.pull_out @ pull.hold", 0.8),
    ]:
        seg = segs[label]
        u, v = _pixel(scene, np.add(seg.start, t * np.subtract(seg.end, seg.start)))
        assert magenta[v - 1 : v + 2, u - 1 : u + 2].any(), (label, t, u, v)
    u, v = _pixel(scene, (0.3, -0.2, 1.0))  # the box's centre is drawn, not background
    assert not (np.abs(img[v, u].astype(int) - round(0.94 * 255)) < 6).all()


def test_instance_pose_and_joints_move_the_picture(toy) -> None:
    """The same box, turned and with its drawer out, is drawn differently but framed again."""
    rng = np.random.default_rng(3)
    inst = toy["ToyBox"].instantiate(pose=random_pose(rng), joints={"slide": 0.2})
    img = render_image(describe(inst, grasps=1), W, H, build_model(inst))
    background = np.all(np.abs(img.astype(int) - round(0.94 * 255)) < 6, axis=2)
    rows, cols = np.nonzero(~background)
    # framed: the drawing reaches near two opposite edges and stays off the others
    assert rows.min() >= 0 and cols.min() >= 0
    assert (rows.max() - rows.min()) / H > 0.75 or (cols.max() - cols.min()) / W > 0.75


def test_primitive_picture_and_png_file(tmp_path) -> None:
    path = write_png(primitive_scene("Cuboid"), tmp_path / "c.png", 640, 480, palette=True)
    assert path.stat().st_size < 100_000
    img = np.asarray(Image.open(path).convert("RGB"))
    assert img.shape == (480, 640, 3)
    for colour in ("red", "green", "blue"):  # the primitive's own frame shows through it
        assert _mask(img, colour).sum() > 50, colour


def test_bad_sizes_are_refused() -> None:
    with pytest.raises(RenderError, match="16..4096"):
        render_image(primitive_scene("Sphere"), 8, 8)

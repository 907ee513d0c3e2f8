"""Offscreen pictures with MuJoCo: ``render_image`` (pixels) and ``write_png`` (a file).

MuJoCo picks its OpenGL backend from ``MUJOCO_GL`` when it is first imported. Without a display
the usual choice fails, so unless the user set it, this module chooses a headless one that is
installed: OSMesa (Debian's ``libosmesa6``, pure software) or EGL (``libegl1``). The MJCF document
(geometry, lights, camera, decorations) is ``mjscene.py``'s.
"""

from __future__ import annotations

import ctypes.util
import importlib.util
import os
import sys
from pathlib import Path
from typing import TYPE_CHECKING, Any

import numpy as np

from grace_dsl.render.camera import frame_scene
from grace_dsl.render.mjscene import CAMERA, DECORATION, scene_mjcf
from grace_dsl.render.scene import Scene
from grace_dsl.runtime.errors import GraceError

if TYPE_CHECKING:
    from grace_dsl.export.model import ExportModel

MAX_SIDE = 4096


class RenderError(GraceError):
    """A picture cannot be made here: no MuJoCo, no OpenGL backend, or a bad image size."""


def headless_backend() -> str | None:
    """The ``MUJOCO_GL`` value to use when the user has not set one: osmesa, egl, or None
    (let MuJoCo try a window system) when neither library is installed."""
    if ctypes.util.find_library("OSMesa"):
        return "osmesa"
    if ctypes.util.find_library("EGL"):
        return "egl"
    return None


def import_mujoco() -> Any:
    """``mujoco``, imported with a headless GL backend unless ``MUJOCO_GL`` says otherwise."""
    if "mujoco" not in sys.modules and "MUJOCO_GL" not in os.environ:
        backend = headless_backend()
        if backend is not None and not os.environ.get("DISPLAY"):
            os.environ["MUJOCO_GL"] = backend
            if backend == "osmesa":
                os.environ.setdefault("PYOPENGL_PLATFORM", "osmesa")
    if importlib.util.find_spec("mujoco") is None:
        raise RenderError("PNG pictures need MuJoCo: pip install 'grace-dsl[sim]'")
    try:
        import mujoco
    except Exception as exc:  # MuJoCo loads its GL backend on import; each fails its own way
        raise RenderError(_no_gl(exc)) from None
    return mujoco


def _no_gl(exc: Exception) -> str:
    backend = os.environ.get("MUJOCO_GL", "default")
    return (
        f"no OpenGL context for offscreen rendering (MUJOCO_GL={backend}: {exc}); install "
        "libosmesa6 and set MUJOCO_GL=osmesa, or libegl1 and set MUJOCO_GL=egl"
    )


def render_image(
    scene: Scene, width: int = 800, height: int = 600, model: ExportModel | None = None
) -> np.ndarray:
    """The scene seen from the front-right-above, (height, width, 3) uint8 RGB."""
    if not (16 <= width <= MAX_SIDE and 16 <= height <= MAX_SIDE):
        raise RenderError(f"image size must be 16..{MAX_SIDE} pixels a side, got {width}x{height}")
    mujoco = import_mujoco()
    view = frame_scene(scene, width / height)
    xml = scene_mjcf(scene, view, width, height, model)
    mj_model = mujoco.MjModel.from_xml_string(xml)
    data = mujoco.MjData(mj_model)
    if mj_model.nkey:
        mujoco.mj_resetDataKeyframe(mj_model, data, 0)  # the instance's joint values
    mujoco.mj_forward(mj_model, data)
    try:
        renderer = mujoco.Renderer(mj_model, height, width)
    except Exception as exc:  # each GL backend fails its own way; all mean "no context here"
        raise RenderError(_no_gl(exc)) from None
    with renderer:
        renderer.update_scene(data, camera=CAMERA)
        _no_decoration_shadows(mujoco, mj_model, renderer.scene)
        return np.asarray(renderer.render(), dtype=np.uint8).copy()


def _no_decoration_shadows(mujoco: Any, mj_model: Any, mjv_scene: Any) -> None:
    """Frames and arrows are annotations, not objects: they cast no shadow on the instance."""
    deco = {i for i in range(mj_model.ngeom) if mj_model.geom(i).name.startswith(DECORATION)}
    for k in range(mjv_scene.ngeom):
        geom = mjv_scene.geoms[k]
        if geom.objtype == mujoco.mjtObj.mjOBJ_GEOM and geom.objid in deco:
            geom.castshadow = 0


def write_png(
    scene: Scene,
    path: str | Path,
    width: int = 800,
    height: int = 600,
    model: ExportModel | None = None,
    palette: bool = False,
) -> Path:
    """Render ``scene`` and save it as PNG; ``palette`` stores 256 colours (about 3x smaller,
    for pictures kept in the repository)."""
    from PIL import Image

    pixels = render_image(scene, width, height, model)
    image = Image.fromarray(pixels, "RGB")
    if palette:
        image = image.quantize(256, method=Image.Quantize.MEDIANCUT, dither=Image.Dither.NONE)
    target = Path(path)
    target.parent.mkdir(parents=True, exist_ok=True)
    image.save(target, format="PNG", optimize=True)
    return target

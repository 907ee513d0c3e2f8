"""An episode replayed for a person: a picture of a moment of it, and every body's motion.

An episode is a pure function of its config and seed, so running it again gives the same motion
and the same last frame: a failure picture or a demo's replay costs one more run of that episode,
never a recording kept for every episode of a bench. Pictures come from MuJoCo's offscreen
renderer (``MUJOCO_GL=osmesa`` or ``egl`` headless), seen from the episode's drawn camera
(azimuth, elevation and distance in the record).
"""

from __future__ import annotations

import math
from pathlib import Path

import mujoco
import numpy as np

from grace_dsl.runtime.errors import GraceError
from grace_dsl.sim.episode import episode_and_world
from grace_dsl.sim.records import EpisodeConfig, EpisodeRecord
from grace_dsl.sim.world import TIMESTEP, World

FPS = 25  # trace frames per simulated second
WIDTH, HEIGHT = 480, 360  # pixels of a picture


class ReplayError(GraceError):
    """A replay has nothing to draw (the hand never moved) or no way to draw it (no OpenGL)."""


def replay(
    config: EpisodeConfig, seed: int, fps: float = FPS
) -> tuple[EpisodeRecord, World | None]:
    """The episode run again with every body's pose traced ``fps`` times a simulated second."""
    every = max(1, round(1.0 / (fps * TIMESTEP))) if fps > 0 else 0
    return episode_and_world(config, seed, trace_every=every)


def render_world(
    world: World,
    camera: dict[str, float],
    path: Path,
    qpos: np.ndarray | None = None,
    size: tuple[int, int] = (WIDTH, HEIGHT),
) -> Path:
    """A PNG of ``world`` (at joint positions ``qpos``, else as it is) from the record's
    ``camera``: azimuth and elevation in degrees, distance in metres, aimed at the object."""
    from PIL import Image

    model, data = world.model, mujoco.MjData(world.model)
    data.qpos[:] = world.data.qpos if qpos is None else qpos
    mujoco.mj_forward(model, data)
    cam = mujoco.MjvCamera()
    cam.type = mujoco.mjtCamera.mjCAMERA_FREE
    cam.lookat[:] = _object_centre(world, data)
    cam.azimuth = float(camera.get("azimuth", 30.0))
    cam.elevation = -float(camera.get("elevation", 35.0))  # MuJoCo's is negative looking down
    cam.distance = float(camera.get("distance", 1.5))
    try:
        renderer = mujoco.Renderer(model, size[1], size[0])
    except Exception as exc:  # each GL backend fails its own way: no context here
        raise ReplayError(
            f"no OpenGL context for a picture ({exc}); set MUJOCO_GL=osmesa or egl"
        ) from None
    with renderer:
        renderer.update_scene(data, camera=cam)
        rgb = renderer.render().copy()
    path.parent.mkdir(parents=True, exist_ok=True)
    Image.fromarray(rgb).save(path)
    return path


def failure_frame(record: EpisodeRecord, path: Path) -> None:
    """``report.FrameRenderer``: the episode of ``record`` run again, its last frame drawn."""
    if record.config.engine != "mujoco":
        raise ReplayError(f"pictures are drawn in MuJoCo, not {record.config.engine!r}")
    again, world = episode_and_world(record.config, record.seed)
    if world is None:
        raise ReplayError(f"the hand never moved ({again.reason}: {again.detail})")
    render_world(world, record.camera, path)


def first_qpos(world: World) -> np.ndarray:
    """The joint positions of the world's first traced frame (its start)."""
    if not world.trace:
        raise ReplayError("the world was not traced: replay it with fps > 0")
    return world.trace[0][1]


def _object_centre(world: World, data: mujoco.MjData) -> np.ndarray:
    """The middle of the object's geoms (the hand left out), where the camera aims."""
    model = world.model
    hand = world.hand_body
    ids = [
        g
        for g in range(model.ngeom)
        if model.geom_bodyid[g] != 0 and not _under(model, int(model.geom_bodyid[g]), hand)
    ]
    if not ids:
        return np.zeros(3)
    pts = data.geom_xpos[ids]
    lo, hi = pts.min(axis=0), pts.max(axis=0)
    centre = (lo + hi) / 2
    return centre if all(map(math.isfinite, centre)) else np.zeros(3)


def _under(model: mujoco.MjModel, body: int, ancestor: int) -> bool:
    while body > 0:
        if body == ancestor:
            return True
        body = int(model.body_parentid[body])
    return False

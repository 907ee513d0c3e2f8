"""Pictures of a planned action: the arm's collision meshes posed by forward kinematics beside
the object posed at the joint value the hand has moved it to.

The arm is drawn from its collision geometry (the URDF's meshes, and boxes where the URDF has
boxes): the geometry the planner checked, so a picture shows what was proven free. A plan's key
frames (pre-grasp, grasp, the middle of the interaction, its end) become one scene each, rendered
into a 2x2 PNG; the whole trajectory becomes an animation for the HTML viewer.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np
import pinocchio as pin

from grace_dsl.render import style
from grace_dsl.render.scene import GraspFrame, MeshPart, Scene

FloatArray = np.ndarray
ARM_COLOR: style.RGB = (0.80, 0.81, 0.84)
HAND_COLOR: style.RGB = (0.35, 0.37, 0.42)
KEY_FRAMES = ("pre-grasp", "grasp", "mid", "end")
# The camera's frame for a plan: the concept convention's front (+z) is the world's +y, its up
# (+y) the world's +z, its right (+x) the world's -x: the view is from the side, turned toward
# the robot, so the arm is seen in front of the object.
SIDE_VIEW = np.column_stack([[-1.0, 0.0, 0.0], [0.0, 0.0, 1.0], [0.0, 1.0, 0.0]])
FPS = 20  # animation frames per second of trajectory


@dataclass(frozen=True, eq=False)
class Animation:
    """Rigid motions of some of a scene's parts: ``tracks[i]`` (F, 4, 4) moves part ``i`` from
    where the scene has it (frame 0) to where it is at ``times[f]``."""

    times: FloatArray
    tracks: dict[int, FloatArray]
    label: str = ""
    values: FloatArray | None = None  # (F,) the object's joint value, shown with the time


def key_frames(plan: Any) -> dict[str, int]:
    """The sample index of each key frame: the end of the approach (pre-grasp), the end of
    moving in (grasp), the middle and the end of the interaction."""
    spans = {name: (start, stop) for name, start, stop in plan.phases}
    begin, end = spans["interact"]
    return {
        "pre-grasp": spans["approach"][1] - 1,
        "grasp": spans["insert"][1] - 1,
        "mid": (begin + end - 1) // 2,
        "end": end - 1,
    }


_MESHES: dict[tuple[str, str], list[tuple[int, FloatArray, FloatArray]]] = {}


def _arm_meshes(robot: Any) -> list[tuple[int, FloatArray, FloatArray]]:
    """(geometry index, vertices in the geometry's frame, faces) of every collision body."""
    key = (robot.name, str(robot.urdf))
    if key in _MESHES:
        return _MESHES[key]
    import trimesh

    out = []
    for k, obj in enumerate(robot.collision.geometryObjects):
        geom = obj.geometry
        mesh: Any
        if Path(obj.meshPath).is_file():
            mesh = trimesh.load_mesh(obj.meshPath)
            mesh.apply_scale(np.asarray(obj.meshScale))
        elif hasattr(geom, "halfSide"):
            mesh = trimesh.creation.box(extents=2 * np.asarray(geom.halfSide))
        elif hasattr(geom, "halfLength"):
            mesh = trimesh.creation.cylinder(geom.radius, 2 * geom.halfLength, sections=16)
        elif hasattr(geom, "radius"):
            mesh = trimesh.creation.icosphere(2, geom.radius)
        else:
            continue
        vertices = np.asarray(mesh.vertices, dtype=np.float64)
        out.append((k, vertices, np.asarray(mesh.faces, dtype=np.int64)))
    _MESHES[key] = out
    return out


def _placements(robot: Any, q: FloatArray, base: FloatArray) -> list[FloatArray]:
    data, gdata = robot.model.createData(), robot.collision.createData()
    pin.updateGeometryPlacements(robot.model, data, robot.collision, gdata, np.asarray(q))
    return [base @ m.homogeneous for m in gdata.oMg]


def arm_parts(robot: Any, q: FloatArray, base: FloatArray) -> list[MeshPart]:
    """The arm at ``q`` (its base at world pose ``base``) as mesh parts in the world."""
    poses = _placements(robot, q, base)
    parts = []
    for k, vertices, faces in _arm_meshes(robot):
        m = poses[k]
        name = str(robot.collision.geometryObjects[k].name)
        color = HAND_COLOR if ("hand" in name or "finger" in name) else ARM_COLOR
        parts.append(MeshPart(f"robot/{name}", vertices @ m[:3, :3].T + m[:3, 3], faces, color))
    return parts


def plan_scene(robot: Any, inst: Any, plan: Any, k: int, title: str) -> Scene:
    """The object at the plan's joint value of sample ``k`` and the arm at ``plan.q[k]``, with
    the gripper frame there (x red, y green: closing, z blue: approach)."""
    posed = inst.with_joints(_joint(plan, k))
    parts = []
    for i, link in enumerate(inst.concept.links):
        mesh = posed.link_mesh(link)
        if len(mesh.faces):
            vertices, faces = np.asarray(mesh.vertices, float), np.asarray(mesh.faces, np.int64)
            parts.append(MeshPart(link, vertices, faces, style.link_color(i)))
    parts += arm_parts(robot, plan.q[k], plan.base)
    view = np.eye(4)
    view[:3, :3] = SIDE_VIEW
    frame = GraspFrame("gripper", plan.base @ robot.fk(plan.q[k]), 0.08)
    return Scene(title, view, tuple(parts), (frame,))


def write_plan_png(
    robot: Any, inst: Any, plan: Any, path: str | Path, width: int = 1200, height: int = 900
) -> Path:
    """The four key frames in a 2x2 picture, each labelled with its name and time."""
    from PIL import Image, ImageDraw

    from grace_dsl.render.png import render_image

    tile_w, tile_h = width // 2, height // 2
    canvas = Image.new("RGB", (2 * tile_w, 2 * tile_h), "white")
    for n, (name, k) in enumerate(key_frames(plan).items()):
        scene = plan_scene(robot, inst, plan, k, inst.concept.name)
        tile = Image.fromarray(render_image(scene, tile_w, tile_h), "RGB")
        label = f"{name}  t = {plan.t[k]:.2f} s"
        if plan.joint:
            label += f"  {plan.joint} = {plan.joint_values[k]:.3f}"
        ImageDraw.Draw(tile).text((10, 8), label, fill=(20, 20, 20))
        canvas.paste(tile, ((n % 2) * tile_w, (n // 2) * tile_h))
    target = Path(path)
    target.parent.mkdir(parents=True, exist_ok=True)
    canvas.save(target, format="PNG", optimize=True)
    return target


def plan_animation(robot: Any, inst: Any, plan: Any, fps: float = FPS) -> tuple[Scene, Animation]:
    """The scene at the plan's first sample and the motions of the arm's and the object's parts
    over the whole trajectory, resampled at ``fps`` (the samples' joint values interpolated)."""
    scene = plan_scene(robot, inst, plan, 0, inst.concept.name)
    count = max(2, math.ceil(plan.duration * fps) + 1)
    times = np.linspace(0.0, plan.duration, count)
    qs = np.column_stack([np.interp(times, plan.t, c) for c in plan.q.T])
    values = np.interp(times, plan.t, plan.joint_values)
    names = [p.link for p in scene.parts]
    tracks: dict[int, list[FloatArray]] = {i: [] for i in range(len(names))}
    start_arm = _placements(robot, plan.q[0], plan.base)
    geoms = robot.collision.geometryObjects
    arm_index = {f"robot/{geoms[k].name}": k for k, _, _ in _arm_meshes(robot)}
    first = inst.with_joints(_joint(plan, 0))
    start_obj = {link: first.link_pose(link) for link in names if link not in arm_index}
    for q, value in zip(qs, values):
        arm = _placements(robot, q, plan.base)
        posed = inst.with_joints({plan.joint: float(value)} if plan.joint else {})
        for i, name in enumerate(names):
            if name in arm_index:
                k = arm_index[name]
                tracks[i].append(arm[k] @ np.linalg.inv(start_arm[k]))
            else:
                tracks[i].append(posed.link_pose(name) @ np.linalg.inv(start_obj[name]))
    moving = {i: np.stack(m) for i, m in tracks.items()}
    label = plan.joint or ""
    return scene, Animation(times, moving, label, values if plan.joint else None)


def _joint(plan: Any, k: int) -> dict[str, float]:
    return {plan.joint: float(plan.joint_values[k])} if plan.joint else {}

"""What a picture of an instance shows, independent of how it is drawn.

A :class:`Scene` holds the instance's meshes per link (world frame, at its joint values), a few
gripper frames of every grasp family, a force arrow for every action at each grasp it uses, and
the moving joints' axes. The PNG (MuJoCo) and HTML (browser) renderers both draw a scene, so the
two pictures agree; ``Scene.segments()`` turns the decorations into coloured line segments.
"""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass, replace
from typing import TYPE_CHECKING, Any

import numpy as np

from grace_dsl.render import style
from grace_dsl.runtime.errors import ParameterError
from grace_dsl.runtime.kinematics import Kinematics
from grace_dsl.runtime.masks import presence

if TYPE_CHECKING:
    from grace_dsl.runtime.instance import Instance

Vec3 = tuple[float, float, float]


def _vec(v: Any) -> Vec3:
    a = np.asarray(v, dtype=float).reshape(3)
    return (float(a[0]), float(a[1]), float(a[2]))


@dataclass(frozen=True, eq=False)
class MeshPart:
    """The solid geometry of one link, in the world."""

    link: str
    vertices: np.ndarray  # (V, 3) float64
    faces: np.ndarray  # (F, 3) int
    color: style.RGB
    opacity: float = 1.0  # < 1 shows what is inside (a primitive's own frame)


@dataclass(frozen=True, eq=False)
class GraspFrame:
    """One gripper pose of a grasp family, drawn as its x (red), y (green), z (blue) axes."""

    grasp: str
    pose: np.ndarray  # (4, 4) world <- gripper
    length: float  # of each axis, metres


@dataclass(frozen=True)
class Force:
    """The direction the gripper at ``grasp`` (its default pose) moves for ``action``; a grasp on
    a revolute joint's axis has no linear force, so it is drawn as the turning axis (``twist``)."""

    action: str
    grasp: str
    origin: Vec3
    direction: Vec3  # unit, world
    twist: bool = False


@dataclass(frozen=True)
class JointAxis:
    """A moving joint's axis through its origin; the direction carries the opening sense."""

    joint: str
    kind: str  # revolute | prismatic | continuous
    origin: Vec3
    direction: Vec3  # unit, world
    span: tuple[float, float]  # where the drawn axis starts and ends, along direction from origin


@dataclass(frozen=True)
class Segment:
    """A drawable line from ``start`` to ``end`` (an arrow head at ``end`` when ``head``)."""

    kind: str  # axis | force | twist | joint
    label: str
    start: Vec3
    end: Vec3
    color: style.RGB
    radius: float
    head: bool


@dataclass(frozen=True, eq=False)
class Scene:
    title: str
    pose: np.ndarray  # world <- concept: the camera looks from its front-right-above, +y up
    parts: tuple[MeshPart, ...]
    frames: tuple[GraspFrame, ...] = ()
    forces: tuple[Force, ...] = ()
    joints: tuple[JointAxis, ...] = ()
    notes: tuple[str, ...] = ()

    @property
    def size(self) -> float:
        """The diagonal of the meshes' bounding box: the scale of every decoration."""
        pts = self.mesh_points()
        if len(pts) == 0:
            return 0.1
        return max(float(np.linalg.norm(pts.max(axis=0) - pts.min(axis=0))), 1e-3)

    def mesh_points(self) -> np.ndarray:
        if not self.parts:
            return np.zeros((0, 3))
        return np.concatenate([p.vertices for p in self.parts])

    def segments(self) -> tuple[Segment, ...]:
        """Every decoration as segments, sized by the scene."""
        size = self.size
        out: list[Segment] = []
        for f in self.frames:
            origin = f.pose[:3, 3]
            for k, color in enumerate(style.FRAME_AXES):
                end = origin + f.length * f.pose[:3, k]
                out.append(_segment("axis", f.grasp, origin, end, color, size, head=False))
        length = float(np.clip(style.FORCE_MIN, style.FORCE_LENGTH * size, style.FORCE_MAX * size))
        for force in self.forces:
            start = np.asarray(force.origin)
            end = start + length * np.asarray(force.direction)
            kind, color = ("twist", style.TWIST) if force.twist else ("force", style.FORCE)
            label = f"{force.action} @ {force.grasp}"
            out.append(_segment(kind, label, start, end, color, size, head=True))
        for j in self.joints:
            o, d = np.asarray(j.origin), np.asarray(j.direction)
            start, end = o + j.span[0] * d, o + j.span[1] * d
            seg = _segment("joint", j.joint, start, end, style.JOINT, size, head=True)
            # thinner than a force arrow: where the two coincide (a drawer's pull), both show
            out.append(replace(seg, radius=seg.radius * style.JOINT_THINNER))
        return tuple(out)

    def bounds(self) -> tuple[np.ndarray, np.ndarray]:
        """The box around the meshes and every decoration (what the camera must frame)."""
        segs = self.segments()
        pts = [self.mesh_points()]
        pts += [np.array([s.start, s.end]) for s in segs]
        all_pts = np.concatenate(pts) if any(len(p) for p in pts) else np.zeros((1, 3))
        return all_pts.min(axis=0), all_pts.max(axis=0)

    def summary(self) -> dict[str, Any]:
        """What the scene shows, JSON-ready (for ``eacc show --json``)."""
        return {
            "concept": self.title,
            "links": [{"link": p.link, "faces": len(p.faces)} for p in self.parts],
            "grasp_frames": {
                g: sum(f.grasp == g for f in self.frames)
                for g in dict.fromkeys(f.grasp for f in self.frames)
            },
            "forces": [
                {
                    "action": f.action,
                    "grasp": f.grasp,
                    "at": list(f.origin),
                    "direction": list(f.direction),
                    "twist": f.twist,
                }
                for f in self.forces
            ],
            "joint_axes": [
                {
                    "joint": j.joint,
                    "kind": j.kind,
                    "origin": list(j.origin),
                    "direction": list(j.direction),
                }
                for j in self.joints
            ],
            "notes": list(self.notes),
        }


def _segment(
    kind: str,
    label: str,
    start: np.ndarray,
    end: np.ndarray,
    color: style.RGB,
    size: float,
    head: bool,
) -> Segment:
    length = float(np.linalg.norm(end - start))
    radius = np.clip(style.LINE_RADIUS * length, style.MIN_RADIUS * size, style.MAX_RADIUS * size)
    return Segment(kind, label, _vec(start), _vec(end), color, float(radius), head)


# -- building scenes ---------------------------------------------------------------------------


def describe(inst: Instance, grasps: int = 3, resolution: int = 48) -> Scene:
    """The scene of an instance: its links' meshes, ``grasps`` poses of every grasp family
    (spread over the free parameters; one if it has none), every action's force at each grasp
    it uses, and the moving joints' axes."""
    if grasps < 0:
        raise ParameterError(f"grasps must be 0 or more, got {grasps}")
    concept = inst.concept
    parts = []
    for i, link in enumerate(inst.links):  # the copies its counts leave out are not drawn
        mesh = inst.link_mesh(link, resolution=resolution)
        if len(mesh.faces):
            parts.append(
                MeshPart(
                    link,
                    np.asarray(mesh.vertices, dtype=float),
                    np.asarray(mesh.faces, dtype=np.int64),
                    style.link_color(i),
                )
            )
    draft = Scene(concept.name, inst.pose.copy(), tuple(parts))
    size = draft.size
    frame = float(np.clip(style.FRAME_MIN, style.FRAME_LENGTH * size, style.FRAME_MAX * size))
    notes: list[str] = []
    return Scene(
        concept.name,
        inst.pose.copy(),
        tuple(parts),
        tuple(_frames(inst, grasps, frame)),
        tuple(_forces(inst, notes)),
        tuple(_joint_axes(inst, draft)),
        tuple(notes),
    )


def _frames(inst: Instance, n: int, length: float) -> list[GraspFrame]:
    out: list[GraspFrame] = []
    if n == 0:
        return out
    here = presence(inst.concept.entry, inst.params)
    for name, entry in inst.concept.grasps.items():
        if not here(name):
            continue
        count = n if entry["free"] else 1
        out += [GraspFrame(name, pose, length) for pose in inst.grasps(name, count)]
    return out


def _forces(inst: Instance, notes: list[str]) -> list[Force]:
    out = []
    here = presence(inst.concept.entry, inst.params)
    for action, entry in inst.concept.actions.items():
        if not here(action):
            continue
        using = [g for g in list(entry["using"]) or list(inst.concept.grasps) if here(g)]
        using = [g for g in using if inst.grasp_applies(g)]  # a `when` that fails here
        if not using:
            notes.append(f"action {action} uses no grasp: no point to draw its force at")
        for grasp in using:
            pose = inst.grasp(grasp)
            try:
                out.append(Force(action, grasp, _vec(pose[:3, 3]), _vec(inst.force(action, pose))))
            except ParameterError:  # on the axis of a turning joint: the hand turns instead
                axis = inst.twist(action)
                out.append(Force(action, grasp, _vec(pose[:3, 3]), _vec(axis), twist=True))
    return out


def _subtree(link: str, joints: Mapping[str, Any]) -> list[str]:
    """``link`` and every link below it."""
    out = [link]
    for j in joints.values():
        if j["parent"] == link:
            out += _subtree(j["child"], joints)
    return out


def _joint_axes(inst: Instance, draft: Scene) -> list[JointAxis]:
    """Each moving joint's axis, long enough to stick out of what it moves: a revolute axis
    spans its child links plus a margin at both ends; a prismatic arrow starts at the front of
    its child links (along the axis) and points the opening way."""
    concept = inst.concept
    if not concept.moving_joints:
        return []
    world = Kinematics.of(inst).joint_axes()  # unit axes and points on them, in the world
    size, out = draft.size, []
    here = presence(inst.concept.entry, inst.params)
    for i, name in enumerate(world.names):
        if not here(name):
            continue
        joint = concept.joints[name]
        d, o = world.axes[i], world.origins[i]
        moved = set(_subtree(joint["child"], concept.joints))
        pts = [p.vertices for p in draft.parts if p.link in moved]
        along = (np.concatenate(pts) - o) @ d if pts else np.zeros(1)
        pad, length = style.JOINT_PAD * size, style.JOINT_LENGTH * size
        if joint["kind"] == "prismatic":
            span = (float(along.max()), float(along.max()) + length)
        else:
            lo, hi = float(along.min()) - pad, float(along.max()) + pad
            grow = max(0.0, length - (hi - lo)) / 2
            span = (lo - grow, hi + grow)
        out.append(JointAxis(name, joint["kind"], _vec(o), _vec(d), span))
    return out


def primitive_scene(name: str, params: dict[str, Any] | None = None, resolution: int = 48) -> Scene:
    """A primitive of the geometry registry at ``params`` (defaults), with its own frame drawn
    as an axis triad: the picture of the primitive's conventions."""
    from grace_dsl.geometry import primitive_mesh, validate

    mesh = primitive_mesh(name, validate(name, params), resolution=resolution)
    part = MeshPart(
        name,
        np.asarray(mesh.vertices, dtype=float),
        np.asarray(mesh.faces, dtype=np.int64),
        style.link_color(0),
        style.PRIMITIVE_OPACITY,
    )
    draft = Scene(name, np.eye(4), (part,))
    frame = GraspFrame("frame", np.eye(4), style.PRIMITIVE_FRAME * draft.size)
    return Scene(name, np.eye(4), (part,), (frame,))

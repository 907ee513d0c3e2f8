"""A format-neutral rigid-body model of an instance, the common input of the URDF and MJCF writers.

The compiled link functions put every link frame on the concept frame when the joints are at 0,
and a joint turns its child about an axis through its origin o. Simulators rotate a child about
its own frame's origin, so each exported link frame sits at its joint origin: the exported frame
of link k is ``E_k(q) = L_k(p, q) @ offset_k`` with ``offset_k = L_k(p, 0)^-1 @ T(o_k)``, and then
``E_child(q) = E_parent(q) @ T(o_child - o_parent) @ M(q)`` with M the joint's own motion about
(or along) the axis, which is what URDF and MJCF describe. Geoms are expressed in these frames.
"""

from __future__ import annotations

import logging
from collections.abc import Mapping
from dataclasses import dataclass, field, replace
from typing import TYPE_CHECKING, Any

import numpy as np
import trimesh

from grace_dsl.export.common import xml_name
from grace_dsl.export.shapes import Geom, link_solids
from grace_dsl.geometry.pieces import SEGMENTS
from grace_dsl.runtime.kinematics import Kinematics
from grace_dsl.runtime.masks import has_masks, present

if TYPE_CHECKING:
    from grace_dsl.runtime.instance import Instance

log = logging.getLogger(__name__)

DENSITY = 600.0  # kg/m^3, wood: a plausible default for doors, drawers and handles
WALL = 0.018  # m, the usual board thickness: large bodies are boxes of boards, not solid blocks
DAMPING = 0.5  # N m s/rad (or N s/m): enough to keep a free-swinging door from ringing
FRICTION = 0.1  # N m (or N): a little static friction, as real hinges and slides have
ARMATURE = 0.01  # kg m^2 (or kg): rotor-like inertia on each joint; keeps light parts stable
HOLD = 3.0  # friction loss at least this times the closed part's pull by gravity (see _held)
SETTLE = 1.0  # s: damping at least inertia / SETTLE, so a heavy door slows like a soft hinge
GRAVITY = np.array([0.0, 0.0, -9.81])  # world, m/s^2 (MuJoCo's default)
NOMINAL_MASS = 0.01  # kg, for links without geometry: simulators reject massless moving bodies
KINDS = {"revolute", "prismatic", "continuous", "fixed"}

Props = tuple[float, np.ndarray, np.ndarray]  # mass, centre of mass, inertia about it (SI)


@dataclass(frozen=True)
class Inertial:
    """Mass, centre of mass and inertia about it, in the link's exported frame (SI)."""

    mass: float
    com: np.ndarray  # (3,)
    inertia: np.ndarray  # (3, 3) about the centre of mass, link axes


@dataclass(frozen=True)
class Link:
    name: str  # sanitized, unique
    source: str  # the concept's qualified link name
    origin: np.ndarray  # (3,) the frame's origin in the concept frame at q = 0 (its joint origin)
    offset: np.ndarray  # (4, 4) exported frame = runtime link pose @ offset
    geoms: tuple[Geom, ...]  # visual: the pieces whole (a board box as its boards)
    inertial: Inertial
    collision: tuple[Geom, ...] = ()  # convex pieces, what a simulator collides


@dataclass(frozen=True)
class Joint:
    name: str  # sanitized, unique
    source: str
    kind: str  # revolute | prismatic | continuous | fixed
    parent: str  # sanitized link names
    child: str
    origin: np.ndarray  # (3,) child frame relative to the parent frame (no rotation)
    axis: np.ndarray  # (3,) unit, in the child frame (zeros for fixed joints)
    lo: float | None  # None: unlimited
    hi: float | None
    value: float  # the instance's joint value: the exported model's initial state
    damping: float
    friction: float
    armature: float = 0.0


@dataclass(frozen=True)
class ExportModel:
    """Links and joints in depth-first tree order (parents before children)."""

    name: str
    pose: np.ndarray  # world <- root link frame
    links: tuple[Link, ...]
    joints: tuple[Joint, ...]
    warnings: tuple[str, ...] = field(default=())

    @property
    def root(self) -> Link:
        return self.links[0]

    def children(self, link: str) -> list[Joint]:
        return [j for j in self.joints if j.parent == link]


@dataclass(frozen=True)
class ExportOptions:
    """How the exported model is made: material (``density`` kg/m^3, ``wall`` m: each solid
    weighs the lesser of its full volume and a shell of this thickness), joint damping,
    friction and armature, mesh segments per full circle, and the collision geometry: convex
    pieces (``segments`` per full turn of a ring, tube or torus), or none (``collision=False``:
    a model to look at)."""

    density: float = DENSITY
    wall: float = WALL
    damping: float = DAMPING
    friction: float = FRICTION
    armature: float = ARMATURE
    resolution: int = 32  # mesh segments per full circle
    segments: int = SEGMENTS
    collision: bool = True


def sanitize(name: str, taken: set[str]) -> str:
    """A name every XML consumer accepts (``handle.pull`` -> ``handle__pull``, ``drawer[2]`` ->
    ``drawer_2``), kept unique within ``taken``."""
    base = xml_name(name) or "unnamed"
    out, i = base, 2
    while out in taken:
        out, i = f"{base}_{i}", i + 1
    taken.add(out)
    return out


def build_model(inst: Instance, options: ExportOptions | None = None) -> ExportModel:
    """The exported rigid-body model of ``inst`` (parameters fixed, joints free)."""
    opts = options or ExportOptions()
    concept = inst.concept
    kin = Kinematics.of(inst).in_concept_frame()
    q0 = np.zeros_like(inst.q)
    at_rest = kin.joint_axes(q0)  # unit axes and their origins, concept frame, closed
    axes, origins = at_rest.axes, at_rest.origins
    lo, hi = kin.joint_limits()
    rest = dict(zip(kin.links, kin.link_poses(q0)))
    joints = concept.entry["joints"]
    if has_masks(concept.entry):  # the copies this instance's counts leave out are not exported
        params = inst.params
        joints = [j for j in joints if present(concept.entry, params, j["child"])]
    root = _root(inst.links, joints)
    order = _depth_first(root, joints)
    link_origin = {root: np.zeros(3)}
    for j in order:
        i = j["index"]
        link_origin[j["child"]] = origins[i] if i is not None else link_origin[j["parent"]]
    names: dict[str, str] = {}
    taken = {"world"}
    for src in [root, *(j["child"] for j in order)]:
        names[src] = sanitize(src, taken)
    warnings: list[str] = []
    links = tuple(
        _link(inst, src, names[src], link_origin[src], rest[src], opts, warnings) for src in names
    )
    out_joints = tuple(
        _joint(j, names, link_origin, axes, lo, hi, inst.q, opts, taken) for j in order
    )
    gravity = inst.pose[:3, :3].T @ GRAVITY  # in the concept frame
    out_joints = tuple(_held(j, links, out_joints, gravity) for j in out_joints)
    for w in warnings:
        log.warning("%s: %s", concept.name, w)
    return ExportModel(concept.name, inst.pose.copy(), links, out_joints, tuple(warnings))


def _root(links: tuple[str, ...], joints: list[Mapping[str, Any]]) -> str:
    children = {j["child"] for j in joints}
    roots = [name for name in links if name not in children]
    if len(roots) != 1:  # the resolver guarantees one tree; say so rather than guess
        raise ValueError(f"expected one root link, found {roots}")
    return roots[0]


def _depth_first(link: str, joints: list[Mapping[str, Any]]) -> list[Mapping[str, Any]]:
    """Joints depth-first from ``link``: parents before children (MJCF nests bodies, and its
    qpos follows that order)."""
    out: list[Mapping[str, Any]] = []
    for j in joints:
        if j["parent"] == link:
            out.append(j)
            out += _depth_first(j["child"], joints)
    return out


def _translation(v: np.ndarray) -> np.ndarray:
    t = np.eye(4)
    t[:3, 3] = v
    return t


def _link(
    inst: Instance,
    src: str,
    name: str,
    origin: np.ndarray,
    rest: np.ndarray,
    opts: ExportOptions,
    warnings: list[str],
) -> Link:
    """The exported link ``src``; ``rest`` is its runtime pose (concept frame) with the joints
    closed."""
    offset = np.linalg.solve(rest, _translation(origin))
    frame = _translation(origin)  # the exported frame in the concept frame at q = 0
    geoms, solid = link_solids(
        inst, src, frame, opts.resolution, warnings, opts.segments, opts.collision
    )
    inertial = _inertial(geoms, opts.density, opts.wall)
    return Link(name, src, origin.copy(), offset, geoms, inertial, solid)


def _joint(
    j: Mapping[str, Any],
    names: Mapping[str, str],
    link_origin: Mapping[str, np.ndarray],
    axes: np.ndarray,
    lo: np.ndarray,
    hi: np.ndarray,
    q: np.ndarray,
    opts: ExportOptions,
    taken: set[str],
) -> Joint:
    i = j["index"]
    kind = j["kind"]
    if kind not in KINDS:
        raise ValueError(f"joint {j['name']}: unsupported kind {kind!r}")
    origin = link_origin[j["child"]] - link_origin[j["parent"]]
    if i is None:
        axis, low, high, value = np.zeros(3), None, None, 0.0
    else:
        axis = axes[i].copy()  # unit: Kinematics.joint_axes normalizes
        low = float(lo[i]) if np.isfinite(lo[i]) else None
        high = float(hi[i]) if np.isfinite(hi[i]) else None
        value = float(q[i])
        if kind == "revolute" and (low is None or high is None):
            kind = "continuous"  # a revolute joint without a range turns freely
    return Joint(
        sanitize(j["name"], taken),
        j["name"],
        kind,
        names[j["parent"]],
        names[j["child"]],
        origin,
        axis,
        low,
        high,
        value,
        opts.damping if kind != "fixed" else 0.0,
        opts.friction if kind != "fixed" else 0.0,
        opts.armature if kind != "fixed" else 0.0,
    )


def _held(
    joint: Joint, links: tuple[Link, ...], joints: tuple[Joint, ...], gravity: np.ndarray
) -> Joint:
    """The joint with enough friction loss to hold its closed part (q = 0) where it is put,
    and damping that grows with what it moves (at least inertia / ``SETTLE``).

    Real doors, flaps, levers and switches stay closed by a latch, a spring or a detent, which
    the concepts do not describe. Where gravity at q = 0 pulls the part (and what hangs on it)
    towards opening (or, for a joint whose range holds 0 inside it, either way), the friction
    loss is raised to ``HOLD`` times that pull, so a closed oven door stays closed; a pull
    into the closed limit needs nothing."""
    if joint.kind == "fixed":
        return joint
    origin = {link.name: link.origin for link in links}  # exported frames at q = 0
    below = _subtree(joint.child, joints)
    pull, inertia = 0.0, 0.0
    for link in links:
        if link.name in below:
            force = link.inertial.mass * gravity
            com = origin[link.name] + link.inertial.com
            if joint.kind == "prismatic":
                pull += float(force @ joint.axis)
                inertia += link.inertial.mass
            else:
                arm = com - origin[joint.child]
                pull += float(np.cross(arm, force) @ joint.axis)
                off = arm - (arm @ joint.axis) * joint.axis
                inertia += float(joint.axis @ link.inertial.inertia @ joint.axis)
                inertia += link.inertial.mass * float(off @ off)
    joint = replace(joint, damping=max(joint.damping, inertia / SETTLE))
    lo, hi = joint.lo, joint.hi
    opening = 0.0 if lo is None or hi is None or lo < 0 < hi else (1.0 if hi > 0 else -1.0)
    if opening != 0.0 and pull * opening <= 0:
        return joint  # pulled into its closed limit: the limit (or a contact) holds it
    return replace(joint, friction=max(joint.friction, HOLD * abs(pull)))


def _subtree(link: str, joints: tuple[Joint, ...]) -> set[str]:
    out = {link}
    for j in joints:
        if j.parent == link:
            out |= _subtree(j.child, joints)
    return out


def _inertial(geoms: tuple[Geom, ...], density: float, wall: float) -> Inertial:
    """Mass properties of a link's geoms (each the lighter of solid and shell, see
    ``mass_properties``; overlaps count twice: plausible, not exact); a small nominal body when
    the link has no geometry."""
    props = [mass_properties(g.mesh_in_link(), density, wall) for g in geoms]
    props = [p for p in props if p[0] > 0]
    if not props:
        inertia = np.eye(3) * NOMINAL_MASS * 0.01**2  # a 1 cm-ish ball
        return Inertial(NOMINAL_MASS, np.zeros(3), inertia)
    mass, com, inertia = _combine(props)
    return Inertial(mass, com, inertia)


def mass_properties(mesh: trimesh.Trimesh, density: float, wall: float) -> Props:
    """A solid's mass properties: a full body (``density`` x volume) or, if lighter, a
    thin-walled shell (``density`` x ``wall`` x area), so a cabinet or a refrigerator weighs
    what its boards would, while a handle or a knob stays solid."""
    volume = abs(float(mesh.volume)) if len(mesh.faces) else 0.0
    if volume <= 0 or density * wall * float(mesh.area) < density * volume:
        return shell_properties(mesh, density * wall)
    return solid_properties(mesh, density)


def solid_properties(mesh: trimesh.Trimesh, density: float) -> Props:
    m = mesh.copy()
    if m.volume < 0:
        m.invert()  # inward faces: trimesh would report a negative mass
    m.density = density
    return float(m.mass), np.asarray(m.center_mass), np.asarray(m.moment_inertia)


def shell_properties(mesh: trimesh.Trimesh, areal_density: float) -> Props:
    """Mass properties of the mesh's surface at ``areal_density`` (kg/m^2), exact over its
    triangles: a triangle of area A and vertices v_i has the second moment
    ``A/12 (sum v_i v_i^T + (sum v_i)(sum v_i)^T)`` and its first moment at its centroid."""
    tri = np.asarray(mesh.triangles, dtype=float)  # (F, 3, 3)
    if not len(tri):
        return 0.0, np.zeros(3), np.zeros((3, 3))
    area = np.linalg.norm(np.cross(tri[:, 1] - tri[:, 0], tri[:, 2] - tri[:, 0]), axis=1) / 2
    total = float(area.sum())
    if total <= 0:
        return 0.0, np.zeros(3), np.zeros((3, 3))
    s = tri.sum(axis=1)  # (F, 3): sum of each triangle's vertices
    second = np.einsum("f,fij->ij", area / 12, np.einsum("fvi,fvj->fij", tri, tri))
    second += np.einsum("f,fi,fj->ij", area / 12, s, s)
    mass = areal_density * total
    com = (area @ s) / 3 / total
    about_origin = areal_density * (np.trace(second) * np.eye(3) - second)
    inertia = about_origin - mass * (com @ com * np.eye(3) - np.outer(com, com))
    return mass, com, (inertia + inertia.T) / 2


def _combine(props: list[Props]) -> Props:
    """Total mass, centre of mass and inertia about it (parallel-axis theorem)."""
    mass = sum(p[0] for p in props)
    com = sum(p[0] * p[1] for p in props) / mass
    inertia = np.zeros((3, 3))
    for m, c, i in props:
        d = c - com
        inertia += i + m * (d @ d * np.eye(3) - np.outer(d, d))
    return float(mass), np.asarray(com, dtype=float), (inertia + inertia.T) / 2

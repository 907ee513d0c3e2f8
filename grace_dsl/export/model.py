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
import re
from collections.abc import Mapping
from dataclasses import dataclass, field
from typing import TYPE_CHECKING, Any

import numpy as np
import trimesh

from grace_dsl.export.shapes import Geom, link_geoms

if TYPE_CHECKING:
    from grace_dsl.runtime.instance import Instance

log = logging.getLogger(__name__)

DENSITY = 600.0  # kg/m^3, wood: a plausible default for doors, drawers and handles
DAMPING = 0.5  # N m s/rad (or N s/m): enough to keep a free-swinging door from ringing
FRICTION = 0.1  # N m (or N): a little static friction, as real hinges and slides have
NOMINAL_MASS = 0.01  # kg, for links without geometry: simulators reject massless moving bodies
KINDS = {"revolute", "prismatic", "continuous", "fixed"}


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
    geoms: tuple[Geom, ...]
    inertial: Inertial


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
    density: float = DENSITY
    damping: float = DAMPING
    friction: float = FRICTION
    resolution: int = 32  # mesh segments per full circle


def sanitize(name: str, taken: set[str]) -> str:
    """A name every XML consumer accepts (``handle.pull`` -> ``handle__pull``), kept unique
    within ``taken``."""
    base = re.sub(r"[^A-Za-z0-9_]", "_", name.replace(".", "__")) or "unnamed"
    out, i = base, 2
    while out in taken:
        out, i = f"{base}_{i}", i + 1
    taken.add(out)
    return out


def build_model(inst: Instance, options: ExportOptions | None = None) -> ExportModel:
    """The exported rigid-body model of ``inst`` (parameters fixed, joints free)."""
    opts = options or ExportOptions()
    concept = inst.concept
    q0 = np.zeros_like(inst.q)
    axes, origins = (np.asarray(x, dtype=float).reshape(-1, 3) for x in _joint_axes(inst, q0))
    lo, hi = (np.atleast_1d(np.asarray(x, dtype=float)).reshape(-1) for x in _limits(inst))
    joints = concept.entry["joints"]
    root = _root(concept.links, joints)
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
        _link(inst, src, names[src], link_origin[src], q0, opts, warnings) for src in names
    )
    out_joints = tuple(
        _joint(j, names, link_origin, axes, lo, hi, inst.q, opts, taken) for j in order
    )
    for w in warnings:
        log.warning("%s: %s", concept.name, w)
    return ExportModel(concept.name, inst.pose.copy(), links, out_joints, tuple(warnings))


def _joint_axes(inst: Instance, q: np.ndarray) -> Any:
    return inst.concept.function("joint_axes")(inst.p, q)


def _limits(inst: Instance) -> Any:
    return inst.concept.function("joint_limits")(inst.p)


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
    q0: np.ndarray,
    opts: ExportOptions,
    warnings: list[str],
) -> Link:
    rest = np.asarray(inst.concept.function("link", src)(inst.p, q0), dtype=float)
    offset = np.linalg.solve(rest, _translation(origin))
    frame = _translation(origin)  # the exported frame in the concept frame at q = 0
    geoms = link_geoms(inst, src, frame, opts.resolution, warnings)
    return Link(name, src, origin.copy(), offset, geoms, _inertial(geoms, opts.density))


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
        axis = axes[i] / np.linalg.norm(axes[i])
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
    )


def _inertial(geoms: tuple[Geom, ...], density: float) -> Inertial:
    """Mass properties of a link's solid geoms at ``density`` (overlaps count twice: plausible,
    not exact); a small nominal body when the link has no geometry."""
    parts = [g.mesh_in_link() for g in geoms]
    parts = [m for m in parts if m is not None and abs(m.volume) > 0]
    if not parts:
        inertia = np.eye(3) * NOMINAL_MASS * 0.01**2  # a 1 cm-ish ball
        return Inertial(NOMINAL_MASS, np.zeros(3), inertia)
    mass, com, inertia = _combine([_props(m, density) for m in parts])
    return Inertial(mass, com, inertia)


def _props(mesh: trimesh.Trimesh, density: float) -> tuple[float, np.ndarray, np.ndarray]:
    m = mesh.copy()
    m.density = density
    return float(m.mass), np.asarray(m.center_mass), np.asarray(m.moment_inertia)


def _combine(
    props: list[tuple[float, np.ndarray, np.ndarray]],
) -> tuple[float, np.ndarray, np.ndarray]:
    """Total mass, centre of mass and inertia about it (parallel-axis theorem)."""
    mass = sum(p[0] for p in props)
    com = sum(p[0] * p[1] for p in props) / mass
    inertia = np.zeros((3, 3))
    for m, c, i in props:
        d = c - com
        inertia += i + m * (d @ d * np.eye(3) - np.outer(d, d))
    return float(mass), np.asarray(com, dtype=float), (inertia + inertia.T) / 2

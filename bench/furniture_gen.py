"""Articulated storage furniture written the way the common datasets ship it, with no concept.

Each model is a layout sampled from catalogue ranges (carcass, plinth or legs, doors, drawers,
handles: bar pulls, or knobs on ``KNOB_SHARE`` of the models), built from boxes and cylinders
with trimesh, and written as a PartNet-Mobility-style directory: ``mobility.urdf`` (a root
link ``base``, one link per rigid part, ``fixed``, ``revolute`` and ``prismatic`` joints whose
``origin`` is a point on the axis), one OBJ per link under ``textured_objs/`` (in the link's
frame), and ``meta.json`` with the sampled truth.

Frame of every model: the origin on the floor under the middle of the carcass's footprint,
+y up, +z out of the front. Nothing here reads ``.eac`` files: the benchmark fits the library's
concepts to these models, so the two must not share code.
"""

from __future__ import annotations

import json
import math
import xml.etree.ElementTree as ET
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np
import trimesh

KNOB_SHARE = 0.3  # the share of models with knobs instead of bar pulls on every front

# layouts the generator draws; which concept (if any) of the library can express each is the
# benchmark's business, not the generator's
LAYOUTS = (
    "door",  # one door over the whole front
    "drawers3",  # three equal drawers stacked
    "drawers2",  # two drawers stacked
    "drawers4",  # four drawers stacked
    "two_doors",  # a pair of doors hinged at the outer edges
    "drawer_over_door",  # a drawer above a door (kitchen base unit)
    "door_beside_blind",  # a door beside a fixed blind panel
    "drawers_side",  # two or three drawers side by side in one row
    "drawers_over_doors",  # two drawers side by side over a pair of doors
)


@dataclass(frozen=True)
class Solid:
    """A box (``kind == "box"``, ``size``) or a cylinder along ``axis`` (``size[0]`` radius,
    ``size[1]`` length), centred at ``center`` in the model frame at the closed state."""

    kind: str
    center: tuple[float, float, float]
    size: tuple[float, ...]
    axis: int = 2

    def mesh(self) -> trimesh.Trimesh:
        if self.kind == "box":
            m = trimesh.creation.box(extents=self.size)
        else:
            m = trimesh.creation.cylinder(radius=self.size[0], height=self.size[1], sections=24)
            if self.axis != 2:
                turn = [0.0, 0.0, 0.0]
                turn[1 - self.axis] = math.pi / 2  # x: about y; y: about x
                m.apply_transform(trimesh.transformations.euler_matrix(*turn))
        return m.apply_translation(self.center)


@dataclass(frozen=True)
class Joint:
    """A moving part's joint: ``origin`` a point on the axis (model frame, closed state)."""

    name: str
    kind: str  # revolute | prismatic
    child: str
    origin: tuple[float, float, float]
    axis: tuple[float, float, float]
    upper: float
    hinge: str = ""  # left | right, for a door, seen from the front


@dataclass
class Model:
    """One generated piece of furniture: solids per link (model frame, closed), joints, the
    sampled joint values and the sampled parameters."""

    name: str
    layout: str
    params: dict[str, Any]
    links: dict[str, list[Solid]] = field(default_factory=dict)
    joints: list[Joint] = field(default_factory=list)
    q: dict[str, float] = field(default_factory=dict)

    def link_mesh(self, link: str) -> trimesh.Trimesh:
        """The link's solids as one mesh, model frame, closed state."""
        merged = trimesh.util.concatenate([s.mesh() for s in self.links[link]])
        assert isinstance(merged, trimesh.Trimesh)
        return merged

    def motion(self, joint: Joint, value: float) -> np.ndarray:
        """The 4x4 motion of the joint's child at ``value``, model frame."""
        m = np.eye(4)
        axis = np.asarray(joint.axis, float)
        if joint.kind == "prismatic":
            m[:3, 3] = value * axis
            return m
        rot = trimesh.transformations.rotation_matrix(value, axis, point=joint.origin)
        return np.asarray(rot)

    def posed_mesh(self, q: dict[str, float] | None = None) -> trimesh.Trimesh:
        """The whole model at joint values ``q`` (default: the sampled ones)."""
        q = self.q if q is None else q
        moved = {j.child: self.motion(j, q.get(j.name, 0.0)) for j in self.joints}
        parts = [self.link_mesh(k).apply_transform(moved.get(k, np.eye(4))) for k in self.links]
        merged = trimesh.util.concatenate(parts)
        assert isinstance(merged, trimesh.Trimesh)
        return merged


def _u(rng: np.random.Generator, lo: float, hi: float) -> float:
    return float(rng.uniform(lo, hi))


# -- parts -------------------------------------------------------------------------------------


def _carcass(w: float, h: float, d: float, b: float, y0: float) -> list[Solid]:
    """Two sides, bottom, top (between the sides) and a back of the same boards; open front.
    ``y0``: height of the carcass's bottom face."""
    yc = y0 + h / 2
    return [
        Solid("box", (-w / 2 + b / 2, yc, 0.0), (b, h, d)),
        Solid("box", (w / 2 - b / 2, yc, 0.0), (b, h, d)),
        Solid("box", (0.0, y0 + b / 2, 0.0), (w - 2 * b, b, d)),
        Solid("box", (0.0, y0 + h - b / 2, 0.0), (w - 2 * b, b, d)),
        Solid("box", (0.0, yc, -d / 2 + b / 2), (w - 2 * b, h - 2 * b, b)),
    ]


def _plinth(w: float, d: float, height: float, recess: float, b: float) -> list[Solid]:
    """A front board set back by ``recess``, a back board and two sides, floor to carcass."""
    z_front, z_back = d / 2 - recess, -d / 2
    depth = z_front - z_back
    zc = (z_front + z_back) / 2
    return [
        Solid("box", (0.0, height / 2, z_front - b / 2), (w - 2 * b, height, b)),
        Solid("box", (0.0, height / 2, z_back + b / 2), (w - 2 * b, height, b)),
        Solid("box", (-w / 2 + b / 2, height / 2, zc), (b, height, depth)),
        Solid("box", (w / 2 - b / 2, height / 2, zc), (b, height, depth)),
    ]


def _legs(w: float, d: float, height: float, r: float) -> list[Solid]:
    inset = 2 * r + 10e-3
    return [
        Solid("cyl", (sx * (w / 2 - inset), height / 2, sz * (d / 2 - inset)), (r, height), 1)
        for sx in (-1, 1)
        for sz in (-1, 1)
    ]


def _bar(center: tuple[float, float, float], length: float, r: float, off: float, vertical: bool):
    """A bar pull on a front face at z = center.z: the bar ``off`` in front, two posts."""
    x, y, z = center
    along = 1 if vertical else 0
    bar = Solid("cyl", (x, y, z + off), (r, length + 2 * r), along)
    posts = []
    for s in (-1, 1):
        c = [x, y, z + off / 2]
        c[along] += s * length / 2
        posts.append(Solid("cyl", (c[0], c[1], c[2]), (r, off), 2))
    return [bar, *posts]


def _knob(center: tuple[float, float, float], knob: dict[str, float]) -> list[Solid]:
    """A mushroom knob on a front face at z = center.z: a stem, then the head in front of it."""
    x, y, z = center
    stem, depth = knob["stem"], knob["depth"]
    return [
        Solid("cyl", (x, y, z + stem / 2), (knob["neck"], stem), 2),
        Solid("cyl", (x, y, z + stem + depth / 2), (knob["radius"], depth), 2),
    ]


def _pull(
    center: tuple[float, float, float],
    handle: dict[str, float],
    vertical: bool,
    knob: dict[str, float] | None,
) -> list[Solid]:
    """The front's handle: the knob when the model has knobs, else the bar."""
    if knob is not None:
        return _knob(center, knob)
    return _bar(center, handle["length"], handle["radius"], handle["standoff"], vertical)


def _knob_sizes(rng: np.random.Generator) -> dict[str, float]:
    """Knob sizes from catalogue ranges: 24-40 mm heads, 14-22 mm deep, on 8-16 mm stems."""
    radius = _u(rng, 0.012, 0.02)
    return {
        "radius": radius,
        "depth": _u(rng, 0.014, 0.022),
        "stem": _u(rng, 0.008, 0.016),
        "neck": radius * _u(rng, 0.35, 0.5),
    }


def _handle(rng: np.random.Generator, span: float) -> dict[str, float]:
    """Bar pull sizes from catalogue ranges (96-320 mm hole spacing, 10-16 mm bars)."""
    length = min(_u(rng, 0.096, 0.32), span)
    return {"length": length, "radius": _u(rng, 0.005, 0.008), "standoff": _u(rng, 0.028, 0.036)}


def _door_pair(
    m: Model,
    rect: tuple[float, float, float, float],
    gap: float,
    z0: float,
    t: float,
    handle: dict[str, float],
    inset: float,
    knob: dict[str, float] | None,
) -> None:
    """Two leaves ``door_l`` and ``door_r`` over ``rect`` (x0, x1, y0, y1), ``gap`` apart in the
    middle, hinged at the outer edges, their handles ``inset`` from the meeting edges."""
    x0, x1, y0, y1 = rect
    _door(m, "door_l", (x0, -gap / 2, y0, y1), z0, t, "left", handle, inset, 0.0, 1.9, knob=knob)
    _door(m, "door_r", (gap / 2, x1, y0, y1), z0, t, "right", handle, inset, 0.0, 1.9, knob=knob)


def _door(
    m: Model,
    name: str,
    rect: tuple[float, float, float, float],
    z0: float,
    t: float,
    hinge: str,
    handle: dict[str, float],
    inset: float,
    dy: float,
    upper: float,
    knob: dict[str, float] | None = None,
) -> None:
    """A door leaf over ``rect`` (x0, x1, y0, y1) with its back face at z0, hinged at the
    ``hinge`` edge's back, a vertical bar (or a knob) ``inset`` from the free edge, ``dy``
    above centre."""
    x0, x1, y0, y1 = rect
    xc, yc = (x0 + x1) / 2, (y0 + y1) / 2
    free = x1 if hinge == "left" else x0
    hx = free - inset if hinge == "left" else free + inset
    m.links[name] = [Solid("box", (xc, yc, z0 + t / 2), (x1 - x0, y1 - y0, t))]
    m.links[name] += _pull((hx, yc + dy, z0 + t), handle, True, knob)
    axis = (0.0, -1.0, 0.0) if hinge == "left" else (0.0, 1.0, 0.0)
    edge = x0 if hinge == "left" else x1
    m.joints.append(
        Joint(f"joint_{len(m.joints)}", "revolute", name, (edge, yc, z0), axis, upper, hinge)
    )


def _drawer(
    m: Model,
    name: str,
    rect: tuple[float, float, float, float],
    z0: float,
    t: float,
    depth: float,
    side_gap: float,
    handle: dict[str, float],
    travel: float,
    knob: dict[str, float] | None = None,
) -> None:
    """A drawer: front over ``rect``, an open tray of 12 mm boards behind it (``side_gap``
    from each side of the front, 20 mm from its top and bottom), runners, a horizontal bar (or
    a knob) in the middle of the front."""
    x0, x1, y0, y1 = rect
    xc, yc = (x0 + x1) / 2, (y0 + y1) / 2
    b = 0.012
    tw, th = (x1 - x0) - 2 * side_gap, (y1 - y0) - 0.04
    zc = z0 - depth / 2
    solids = [Solid("box", (xc, yc, z0 + t / 2), (x1 - x0, y1 - y0, t))]
    solids += [
        Solid("box", (xc - tw / 2 + b / 2, yc, zc), (b, th, depth)),
        Solid("box", (xc + tw / 2 - b / 2, yc, zc), (b, th, depth)),
        Solid("box", (xc, yc - th / 2 + b / 2, zc), (tw - 2 * b, b, depth)),
        Solid("box", (xc, yc + b / 2, z0 - b / 2), (tw - 2 * b, th - b, b)),
        Solid("box", (xc, yc + b / 2, z0 - depth + b / 2), (tw - 2 * b, th - b, b)),
    ]
    for s in (-1, 1):  # the moving runner members on the tray's sides
        solids.append(
            Solid("box", (xc + s * (tw / 2 + 0.003), yc - th / 2 + 0.02, zc), (0.006, 0.024, depth))
        )
    solids += _pull((xc, yc, z0 + t), handle, False, knob)
    m.links[name] = solids
    m.joints.append(
        Joint(f"joint_{len(m.joints)}", "prismatic", name, (xc, yc, z0), (0.0, 0.0, 1.0), travel)
    )


# -- layouts -------------------------------------------------------------------------------------


def sample_model(layout: str, seed: int) -> Model:
    """One model of ``layout`` with sizes drawn from catalogue ranges (seeded)."""
    if layout not in LAYOUTS:
        raise ValueError(f"unknown layout {layout!r}; layouts: {', '.join(LAYOUTS)}")
    rng = np.random.default_rng(seed)
    drawers = layout.startswith("drawers") and layout not in ("drawers_side", "drawers_over_doors")
    w = _u(rng, 0.5, 1.0) if drawers else _u(rng, 0.4, 0.9)
    if layout in ("two_doors", "door_beside_blind", "drawers_over_doors"):
        w = _u(rng, 0.7, 1.1)
    h = _u(rng, 0.6, 1.0) if drawers else _u(rng, 0.55, 0.9)
    if layout == "drawers_side":  # a low chest or sideboard: one row of wide drawers
        w, h = _u(rng, 0.8, 1.2), _u(rng, 0.25, 0.45)
    d = _u(rng, 0.38, 0.58)
    b = _u(rng, 0.015, 0.019)
    legs = layout == "door_beside_blind" or (layout == "drawers4" and rng.random() < 0.5)
    base_h = _u(rng, 0.1, 0.2) if legs else _u(rng, 0.06, 0.12)
    recess = _u(rng, 0.03, 0.07)
    t = _u(rng, 0.016, 0.02)
    gap = 0.003
    params = {
        "width": w,
        "height": h,
        "depth": d,
        "board": b,
        "base_height": base_h,
        "legs": legs,
        "recess": recess,
        "front": t,
    }
    # the handle type from a stream of its own, so that a bar model's sizes stay what they were
    # before knobs were drawn
    kind_rng = np.random.default_rng([seed, 7])
    knob = _knob_sizes(kind_rng) if kind_rng.random() < KNOB_SHARE else None
    params["handle_kind"] = "knob" if knob else "bar"
    if knob:
        params["knob"] = knob
    m = Model(f"{layout}_{seed}", layout, params)
    y0 = base_h
    m.links["body"] = _carcass(w, h, d, b, y0)
    m.links["body"] += _legs(w, d, base_h, 0.02) if legs else _plinth(w, d, base_h, recess, b)
    z0 = d / 2
    inner = (-w / 2 + gap, w / 2 - gap)
    top, bottom = y0 + h - gap, y0 + gap
    depth = d - b - _u(rng, 0.015, 0.04)
    travel = depth * _u(rng, 0.6, 0.9)
    if drawers or layout in ("drawer_over_door", "drawers_side", "drawers_over_doors"):
        handle = _handle(
            rng, (w - 0.1) / {"drawers_side": 3, "drawers_over_doors": 2}.get(layout, 1)
        )
        params["drawer_handle"] = handle
    if layout == "door" or layout == "door_beside_blind":
        x0, x1 = inner
        if layout == "door_beside_blind":  # the blind panel is fixed to the body
            split = _u(rng, 0.35, 0.5) * w
            side = "left" if rng.random() < 0.5 else "right"
            xb = (-w / 2 + gap, -w / 2 + split) if side == "left" else (w / 2 - split, w / 2 - gap)
            x0, x1 = (xb[1] + gap, x1) if side == "left" else (x0, xb[0] - gap)
            m.links["body"].append(
                Solid(
                    "box",
                    ((xb[0] + xb[1]) / 2, (top + bottom) / 2, z0 + t / 2),
                    (xb[1] - xb[0], top - bottom, t),
                )
            )
        hinge = "left" if rng.random() < 0.5 else "right"
        dh = _handle(rng, h - 0.1)
        params["door_handle"] = dh
        inset = _u(rng, 0.04, 0.07) if knob is None else _u(kind_rng, 0.05, 0.07)
        dy = _u(rng, 0.0, 0.3) * (top - bottom) / 2 - 0.0
        dy = min(dy, (top - bottom) / 2 - dh["length"] / 2 - dh["radius"] - 0.01)
        _door(
            m,
            "door",
            (x0, x1, bottom, top),
            z0,
            t,
            hinge,
            dh,
            inset,
            dy,
            math.radians(110),
            knob=knob,
        )
        params.update(hinge=hinge, handle_inset=inset, handle_dy=dy)
    elif layout == "two_doors":
        dh = _handle(rng, h - 0.1)
        inset = _u(rng, 0.04, 0.07) if knob is None else _u(kind_rng, 0.05, 0.07)
        _door_pair(m, (inner[0], inner[1], bottom, top), gap, z0, t, dh, inset, knob)
    elif drawers:
        n = int(layout[-1])
        fh = (top - bottom - (n - 1) * gap) / n
        for i in range(n):
            y1 = top - i * (fh + gap)
            _drawer(
                m,
                f"drawer_{i}",
                (*inner, y1 - fh, y1),
                z0,
                t,
                depth,
                b + 0.013,
                handle,
                travel,
                knob=knob,
            )
    elif layout == "drawers_side":
        n = 2 + int(rng.random() < 0.5)
        fw = (inner[1] - inner[0] - (n - 1) * gap) / n
        for i in range(n):
            x0 = inner[0] + i * (fw + gap)
            _drawer(
                m,
                f"drawer_{i}",
                (x0, x0 + fw, bottom, top),
                z0,
                t,
                depth,
                b + 0.013,
                handle,
                travel,
                knob=knob,
            )
    elif layout == "drawers_over_doors":
        fh = _u(rng, 0.12, 0.2)
        fw = (inner[1] - inner[0] - gap) / 2
        for i in range(2):
            x0 = inner[0] + i * (fw + gap)
            rect = (x0, x0 + fw, top - fh, top)
            _drawer(m, f"drawer_{i}", rect, z0, t, depth, b + 0.013, handle, travel, knob=knob)
        dh = _u(rng, 0.096, min(0.32, h - fh - 0.1))
        dh_ = {"length": dh, "radius": handle["radius"], "standoff": handle["standoff"]}
        inset = _u(rng, 0.04, 0.07) if knob is None else _u(kind_rng, 0.05, 0.07)
        door_top = top - fh - gap
        _door_pair(m, (inner[0], inner[1], bottom, door_top), gap, z0, t, dh_, inset, knob)
        params.update(drawer_height=fh, door_handle=dh_, handle_inset=inset)
    else:  # drawer over door
        fh = _u(rng, 0.12, 0.2)
        _drawer(
            m,
            "drawer_0",
            (*inner, top - fh, top),
            z0,
            t,
            depth,
            b + 0.013,
            handle,
            travel,
            knob=knob,
        )
        hinge = "left" if rng.random() < 0.5 else "right"
        dh = _handle(rng, h - fh - 0.1)
        _door(
            m, "door", (*inner, bottom, top - fh - gap), z0, t, hinge, dh, 0.05, 0.1, 1.9, knob=knob
        )
    for j in m.joints:  # a random state between closed and 80 % open
        m.q[j.name] = float(rng.uniform(0.0, 0.8 * j.upper))
    return m


def sample_models(n: int, seed: int) -> list[Model]:
    """``n`` models cycling through a seeded shuffle of the layouts' mix: the layouts the
    library's first fixed concepts expressed come up twice (door, drawers3), the rest once."""
    rng = np.random.default_rng(seed)
    mix = ["door", "drawers3"] * 2 + list(LAYOUTS[2:])
    order = [mix[i % len(mix)] for i in range(n)]
    return [sample_model(layout, int(rng.integers(2**31))) for layout in order]


# -- writing -----------------------------------------------------------------------------------


def _inertial(link: ET.Element, mesh: trimesh.Trimesh, offset: np.ndarray) -> None:
    """Mass and inertia of the link's solids (600 kg/m^3, chipboard), in the link frame."""
    mass = max(float(sum(abs(s.volume) for s in mesh.split(only_watertight=False))) * 600, 1e-3)
    com = np.asarray(mesh.bounds.mean(axis=0)) - offset
    ext = np.ptp(mesh.bounds, axis=0)
    inertia = (
        mass
        / 12
        * np.array(
            [ext[1] ** 2 + ext[2] ** 2, ext[0] ** 2 + ext[2] ** 2, ext[0] ** 2 + ext[1] ** 2]
        )
    )
    el = ET.SubElement(link, "inertial")
    ET.SubElement(el, "origin", xyz=" ".join(f"{v:.6f}" for v in com), rpy="0 0 0")
    ET.SubElement(el, "mass", value=f"{mass:.6f}")
    ET.SubElement(
        el,
        "inertia",
        ixx=f"{inertia[0]:.6g}",
        ixy="0",
        ixz="0",
        iyy=f"{inertia[1]:.6g}",
        iyz="0",
        izz=f"{inertia[2]:.6g}",
    )


def write_model(m: Model, root: Path) -> Path:
    """Write ``mobility.urdf``, ``textured_objs/<link>.obj`` and ``meta.json`` under
    ``root / m.name``; returns the URDF's path. Each link's frame is its joint's origin (the
    body's is the model frame), as in PartNet-Mobility."""
    out = root / m.name
    (out / "textured_objs").mkdir(parents=True, exist_ok=True)
    robot = ET.Element("robot", name=m.name)
    ext = ET.SubElement(robot, "mujoco")
    ET.SubElement(ext, "compiler", strippath="false", discardvisual="false")
    ET.SubElement(robot, "link", name="base")
    origin = {j.child: np.asarray(j.origin, float) for j in m.joints}
    for name in m.links:
        offset = origin.get(name, np.zeros(3))
        mesh = m.link_mesh(name).apply_translation(-offset)
        mesh.export(out / "textured_objs" / f"{name}.obj", file_type="obj", digits=9)
        link = ET.SubElement(robot, "link", name=name)
        _inertial(link, m.link_mesh(name), offset)
        for tag in ("visual", "collision"):
            el = ET.SubElement(link, tag, name=f"{name}-{tag}")
            ET.SubElement(el, "origin", xyz="0 0 0", rpy="0 0 0")
            geom = ET.SubElement(el, "geometry")
            ET.SubElement(geom, "mesh", filename=f"textured_objs/{name}.obj")
    joints = [("joint_body", "fixed", "body", np.zeros(3), None, None)]
    joints += [(j.name, j.kind, j.child, np.asarray(j.origin), j.axis, j.upper) for j in m.joints]
    for name, kind, child, xyz, axis, upper in joints:
        el = ET.SubElement(robot, "joint", name=name, type=kind)
        ET.SubElement(el, "origin", xyz=" ".join(f"{v:.9f}" for v in xyz), rpy="0 0 0")
        ET.SubElement(el, "child", link=child)
        ET.SubElement(el, "parent", link="base")
        if axis is not None:
            ET.SubElement(el, "axis", xyz=" ".join(f"{v:g}" for v in axis))
            ET.SubElement(el, "limit", lower="0", upper=f"{upper:.9f}", effort="100", velocity="1")
    ET.indent(robot)
    urdf = out / "mobility.urdf"
    urdf.write_text(ET.tostring(robot, encoding="unicode") + "\n")
    meta = {
        "name": m.name,
        "layout": m.layout,
        "params": m.params,
        "q": m.q,
        "joints": [
            {
                "name": j.name,
                "type": j.kind,
                "child": j.child,
                "origin": list(j.origin),
                "axis": list(j.axis),
                "upper": j.upper,
                "hinge": j.hinge,
            }
            for j in m.joints
        ],
    }
    (out / "meta.json").write_text(json.dumps(meta, indent=1))
    return urdf

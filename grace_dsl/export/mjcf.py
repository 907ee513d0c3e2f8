"""MJCF (MuJoCo) export: nested bodies following the joint tree, the root welded to the world.

The root body carries the instance pose (``pos`` and ``quat``, w x y z). MuJoCo's ``qpos0`` is
the model at q = 0 (where the bodies are written); the instance's joint values are the keyframe
``instance``: ``mujoco.mj_resetDataKeyframe(model, data, 0)`` starts the simulation there.
Boxes, full cylinders, spheres and capsules are native geoms; the rest are STL meshes (inline
vertex/face data when no path is given, so the text alone is a complete model).

Each link has two sets of geoms. The visual ones (group 2, ``contype = conaffinity = 0``) are
the pieces whole, for pictures and cameras; the collision ones (group 3, invisible by default,
named ``<piece>__collision``) are convex, because MuJoCo collides a mesh as its convex hull
(see ``shapes.link_solids``). A model built with ``ExportOptions(collision=False)`` has only
visual geoms, and those collide. Joints carry damping, friction loss and armature.
"""

from __future__ import annotations

import xml.etree.ElementTree as ET
from dataclasses import replace
from pathlib import Path
from typing import TYPE_CHECKING

import numpy as np

from grace_dsl.export.common import (
    geom_file_stem,
    mesh_dir_name,
    num,
    output_file,
    quat_wxyz,
    to_text,
    vec,
    write_mesh,
)
from grace_dsl.export.model import ExportModel, ExportOptions, Inertial, Joint, Link, build_model
from grace_dsl.export.shapes import Geom

if TYPE_CHECKING:
    from grace_dsl.runtime.instance import Instance

MJCF_NATIVE = {"box", "cylinder", "sphere", "capsule"}
JOINT_TYPES = {"revolute": "hinge", "continuous": "hinge", "prismatic": "slide"}
OVERLAP = 0.0001  # m: a deeper overlap at q = 0 is drawn on purpose (``overlapping_bodies``)
VISUAL = {"group": "2", "contype": "0", "conaffinity": "0"}
COLLISION = {  # stiff contacts: a lid falling shut must not sink a millimetre into its box
    "group": "3",
    "contype": "1",
    "conaffinity": "1",
    "rgba": "0.5 0.5 0.5 0.4",
    "solref": "0.004 1",
    "solimp": "0.95 0.99 0.001",
}


def export_mjcf(
    inst: Instance, path: str | Path | None = None, options: ExportOptions | None = None
) -> str:
    """The MJCF text of ``inst``; with ``path``, also write it and its meshes
    (``<stem>_meshes/`` next to it, referenced relatively)."""
    return write_mjcf(build_model(inst, options), path)


def write_mjcf(
    model: ExportModel, path: str | Path | None = None, exclude_overlaps: bool = True
) -> str:
    """The MJCF text of an already built model (written to ``path`` when given); with
    ``exclude_overlaps``, bodies whose collision geoms overlap at q = 0 do not collide."""
    target = output_file(path, ".xml") if path is not None else None
    writer = _Writer(model, target, exclude_overlaps)
    text = to_text(writer.tree(), f"{model.name}, exported by grace_dsl")
    if target is not None:
        target.parent.mkdir(parents=True, exist_ok=True)
        target.write_text(text, encoding="utf-8")
    return text


class _Writer:
    def __init__(self, model: ExportModel, target: Path | None, exclude: bool = True):
        self.model, self.exclude = model, exclude
        self.relative = mesh_dir_name(target) if target is not None else ""
        self.mesh_dir = target.parent / self.relative if target is not None else None
        self.assets = ET.Element("asset")

    def tree(self) -> ET.Element:
        root = ET.Element("mujoco", model=self.model.name)
        ET.SubElement(root, "compiler", angle="radian", inertiafromgeom="false")
        world = ET.Element("worldbody")
        world.append(self._body(self.model.root, None, self.model.pose))
        if len(self.assets):
            root.append(self.assets)
        root.append(world)
        moving = [j for j in self.model.joints if j.kind != "fixed"]
        pairs = overlapping_bodies(write_mjcf(self.model, None, False)) if self.exclude else []
        if pairs:
            contact = ET.SubElement(root, "contact")
            for a, b in pairs:
                ET.SubElement(contact, "exclude", body1=a, body2=b)
        if moving:
            frames = ET.SubElement(root, "keyframe")
            ET.SubElement(frames, "key", name="instance", qpos=vec(j.value for j in moving))
        return root

    def _body(self, link: Link, joint: Joint | None, pose: np.ndarray) -> ET.Element:
        el = ET.Element("body", name=link.name, pos=vec(pose[:3, 3]))
        if not np.allclose(pose[:3, :3], np.eye(3), atol=0, rtol=0):
            el.set("quat", vec(quat_wxyz(pose[:3, :3])))
        el.append(_inertial(link.inertial))
        if joint is not None and joint.kind != "fixed":
            el.append(_joint(joint))
        colliding = not link.collision  # without collision geoms the visual ones collide
        for geom in link.geoms:
            el.append(self._role(self._geom(geom), VISUAL if not colliding else COLLISION))
        for geom in link.collision:
            named = replace(geom, name=f"{geom.name}.collision")
            el.append(self._role(self._geom(named), COLLISION))
        for j in self.model.children(link.name):
            child = next(x for x in self.model.links if x.name == j.child)
            offset = np.eye(4)
            offset[:3, 3] = j.origin
            el.append(self._body(child, j, offset))
        return el

    @staticmethod
    def _role(el: ET.Element, attrs: dict[str, str]) -> ET.Element:
        for k, v in attrs.items():
            el.set(k, v)
        return el

    def _geom(self, geom: Geom) -> ET.Element:
        el = ET.Element("geom", name=geom_file_stem(geom))
        el.set("pos", vec(geom.pose[:3, 3]))
        el.set("quat", vec(quat_wxyz(geom.pose[:3, :3])))
        native = geom.native()
        if native is None:
            el.set("type", "mesh")
            el.set("mesh", self._mesh(geom))
            return el
        kind, dims = native
        el.set("type", kind)
        if kind == "box":
            el.set("size", vec(d / 2 for d in dims))
        elif kind == "sphere":
            el.set("size", num(dims[0]))
        else:  # cylinder, capsule: radius and half the length of the straight part
            el.set("size", vec((dims[0], dims[1] / 2)))
        return el

    def _mesh(self, geom: Geom) -> str:
        name = geom_file_stem(geom)
        asset = ET.SubElement(self.assets, "mesh", name=name)
        if self.mesh_dir is None:
            asset.set("vertex", vec(np.asarray(geom.mesh.vertices).reshape(-1)))
            asset.set("face", " ".join(str(int(i)) for i in np.asarray(geom.mesh.faces).ravel()))
        else:
            asset.set("file", write_mesh(geom, self.mesh_dir, self.relative, "stl"))
        return name


def overlapping_bodies(text: str) -> list[tuple[str, str]]:
    """Pairs of bodies of an MJCF model whose geoms overlap by more than ``OVERLAP`` in the
    state it is written in (q = 0); empty when MuJoCo is not installed.

    Some concepts draw a part inside a solid stand-in for its parent (a drawer box in a solid
    carcass block, a trolley's tubes in a suitcase shell): the part is meant to slide there,
    so the pair is excluded from collision instead of being pushed apart at the first step."""
    try:
        import mujoco
    except ImportError:
        return []
    model = mujoco.MjModel.from_xml_string(text)
    data = mujoco.MjData(model)
    mujoco.mj_forward(model, data)
    pairs: set[tuple[str, str]] = set()
    for c in data.contact[: data.ncon]:
        if -c.dist > OVERLAP:
            b1, b2 = sorted((int(model.geom_bodyid[c.geom1]), int(model.geom_bodyid[c.geom2])))
            pairs.add((model.body(b1).name, model.body(b2).name))
    return sorted(pairs)


def _inertial(i: Inertial) -> ET.Element:
    m = i.inertia
    full = (m[0, 0], m[1, 1], m[2, 2], m[0, 1], m[0, 2], m[1, 2])
    return ET.Element("inertial", pos=vec(i.com), mass=num(i.mass), fullinertia=vec(full))


def _joint(j: Joint) -> ET.Element:
    el = ET.Element("joint", name=j.name, type=JOINT_TYPES[j.kind], axis=vec(j.axis))
    el.set("damping", num(j.damping))
    el.set("frictionloss", num(j.friction))
    # a stiff friction loss: MuJoCo's default softness lets a held part creep ~5 mm/s
    el.set("solreffriction", "0.004 1")
    el.set("solimpfriction", "0.99 0.999 0.001")
    if j.armature > 0:
        el.set("armature", num(j.armature))
    if j.lo is not None and j.hi is not None:
        el.set("limited", "true")
        el.set("solreflimit", "0.004 1")
        el.set("solimplimit", "0.95 0.99 0.001")
        el.set("range", vec((j.lo, j.hi)))
    else:
        el.set("limited", "false")
    return el

"""URDF export: one link per concept link, a fixed joint from ``world`` holding the instance pose.

URDF has no initial joint state: the exported file describes the model at q = 0; the instance's
joint values are only reported (``export_urdf`` logs nothing about them; callers set them in the
simulator). Boxes, full cylinders and spheres are native; everything else is an OBJ mesh.

Each link's ``<visual>`` elements are its pieces whole; its ``<collision>`` elements are the convex
pieces (``ExportModel`` ``Link.collision``), since simulators collide a mesh as its convex hull;
a model built without collision pieces collides its whole pieces. ``visual=False`` leaves the
visual elements out: a simulator scene without a renderer (SAPIEN's PhysX system alone) refuses
to load them.
"""

from __future__ import annotations

import logging
import xml.etree.ElementTree as ET
from dataclasses import replace
from pathlib import Path
from typing import TYPE_CHECKING

import numpy as np

from grace_dsl.export.common import (
    mesh_dir_name,
    num,
    output_file,
    rpy,
    to_text,
    vec,
    write_mesh,
)
from grace_dsl.export.model import ExportModel, ExportOptions, Inertial, Joint, Link, build_model
from grace_dsl.export.shapes import Geom

if TYPE_CHECKING:
    from grace_dsl.runtime.instance import Instance

log = logging.getLogger(__name__)

URDF_NATIVE = {"box", "cylinder", "sphere"}
EFFORT, VELOCITY = 100.0, 2.0  # required by the URDF schema for limited joints; generous values


def export_urdf(
    inst: Instance,
    path: str | Path | None = None,
    options: ExportOptions | None = None,
    visual: bool = True,
) -> str:
    """The URDF text of ``inst``; with ``path``, also write it and its meshes (``<stem>_meshes/``).

    Without a path the meshes are referenced (as if written next to ``model.urdf``) but not
    written: pass a path for a loadable model whenever the concept has non-native shapes.
    ``visual=False``: collision elements only (see the module docstring)."""
    return write_urdf(build_model(inst, options), path, visual)


def write_urdf(model: ExportModel, path: str | Path | None = None, visual: bool = True) -> str:
    """The URDF text of an already built model (written to ``path`` when given)."""
    target = output_file(path, ".urdf") if path is not None else None
    relative = mesh_dir_name(target or Path("model.urdf"))
    mesh_dir = target.parent / relative if target is not None else None
    pieces = [g for link in model.links for g in (*link.geoms, *link.collision)]
    if target is None and any(g.native() is None for g in pieces):
        log.warning("%s: meshes are referenced but not written (no path given)", model.name)
    text = to_text(urdf_tree(model, mesh_dir, relative, visual), _comment(model))
    if target is not None:
        target.parent.mkdir(parents=True, exist_ok=True)
        target.write_text(text, encoding="utf-8")
    return text


def _comment(model: ExportModel) -> str:
    state = ", ".join(f"{j.source}={num(j.value)}" for j in model.joints if j.kind != "fixed")
    return (
        f"{model.name}, exported by grace_dsl. URDF has no initial state; "
        f"the instance's joint values were: {state or 'none'}"
    )


def urdf_tree(
    model: ExportModel, mesh_dir: Path | None, relative: str, visual: bool = True
) -> ET.Element:
    robot = ET.Element("robot", name=model.name)
    ET.SubElement(robot, "link", name="world")
    place = ET.SubElement(robot, "joint", name="world_joint", type="fixed")
    ET.SubElement(place, "parent", link="world")
    ET.SubElement(place, "child", link=model.root.name)
    _origin(place, model.pose)
    for link in model.links:
        robot.append(_link(link, mesh_dir, relative, visual))
    for joint in model.joints:
        robot.append(_joint(joint))
    return robot


def _origin(parent: ET.Element, pose: np.ndarray) -> None:
    ET.SubElement(parent, "origin", xyz=vec(pose[:3, 3]), rpy=vec(rpy(pose[:3, :3])))


def _link(link: Link, mesh_dir: Path | None, relative: str, visual: bool = True) -> ET.Element:
    el = ET.Element("link", name=link.name)
    el.append(_inertial(link.inertial))
    if visual:
        for geom in link.geoms:
            _element(el, "visual", geom, mesh_dir, relative)
    if not link.collision:  # a model built without collision pieces collides its whole pieces
        for geom in link.geoms:
            _element(el, "collision", geom, mesh_dir, relative)
    for geom in link.collision:  # convex: a simulator collides a mesh as its hull
        _element(el, "collision", replace(geom, name=f"{geom.name}.collision"), mesh_dir, relative)
    return el


def _element(el: ET.Element, tag: str, geom: Geom, mesh_dir: Path | None, relative: str) -> None:
    g = ET.SubElement(el, tag, name=geom.name)
    _origin(g, geom.pose)
    g.append(_geometry(geom, mesh_dir, relative))


def _inertial(i: Inertial) -> ET.Element:
    el = ET.Element("inertial")
    ET.SubElement(el, "origin", xyz=vec(i.com), rpy="0 0 0")
    ET.SubElement(el, "mass", value=num(i.mass))
    m = i.inertia
    ET.SubElement(
        el,
        "inertia",
        ixx=num(m[0, 0]),
        ixy=num(m[0, 1]),
        ixz=num(m[0, 2]),
        iyy=num(m[1, 1]),
        iyz=num(m[1, 2]),
        izz=num(m[2, 2]),
    )
    return el


def _geometry(geom: Geom, mesh_dir: Path | None, relative: str) -> ET.Element:
    el = ET.Element("geometry")
    native = geom.native()
    if native is not None and native[0] in URDF_NATIVE:
        kind, dims = native
        if kind == "box":
            ET.SubElement(el, "box", size=vec(dims))
        elif kind == "sphere":
            ET.SubElement(el, "sphere", radius=num(dims[0]))
        else:
            ET.SubElement(el, "cylinder", radius=num(dims[0]), length=num(dims[1]))
        return el
    ET.SubElement(el, "mesh", filename=write_mesh(geom, mesh_dir, relative, "obj"))
    return el


def _joint(j: Joint) -> ET.Element:
    el = ET.Element("joint", name=j.name, type=j.kind)
    ET.SubElement(el, "parent", link=j.parent)
    ET.SubElement(el, "child", link=j.child)
    ET.SubElement(el, "origin", xyz=vec(j.origin), rpy="0 0 0")
    if j.kind == "fixed":
        return el
    ET.SubElement(el, "axis", xyz=vec(j.axis))
    if j.kind in ("revolute", "prismatic"):
        assert j.lo is not None and j.hi is not None
        limit = ET.SubElement(el, "limit", lower=num(j.lo), upper=num(j.hi))
        limit.set("effort", num(EFFORT))
        limit.set("velocity", num(VELOCITY))
    ET.SubElement(el, "dynamics", damping=num(j.damping), friction=num(j.friction))
    return el

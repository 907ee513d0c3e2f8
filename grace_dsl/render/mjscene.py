"""The MJCF document a PNG is rendered from: the exported instance, coloured, lit, with a camera.

An instance goes through the MJCF exporter (``grace_dsl.export``), so the picture shows exactly
the model a simulation would load, posed by its keyframe; a scene without an instance (a
primitive) becomes static mesh geoms. Then materials per link, a neutral flat sky, a key and a
fill light and the framing camera ``view`` are added, and the decorations as static world geoms
that touch nothing: a capsule per frame axis, a cylinder and a cone (a small mesh) per arrow.
MuJoCo's own arrow geoms are not used: their drawn length is not the connector's length in every
MuJoCo version.
"""

from __future__ import annotations

import xml.etree.ElementTree as ET
from collections.abc import Mapping

import numpy as np

from grace_dsl.export.common import num, vec
from grace_dsl.export.mjcf import write_mjcf
from grace_dsl.export.model import ExportModel
from grace_dsl.render import style
from grace_dsl.render.camera import View
from grace_dsl.render.scene import Scene, Segment
from grace_dsl.tolerances import DEGENERATE

CAMERA = "view"
DECORATION = "deco"  # the name prefix of decoration geoms


def scene_mjcf(
    scene: Scene, view: View, width: int, height: int, model: ExportModel | None = None
) -> str:
    """MJCF text of ``scene`` seen from ``view`` at ``width`` x ``height`` pixels; the geometry
    comes from ``model`` (the exported instance) when given, else from the scene's meshes."""
    paint = {p.link: (p.color, p.opacity) for p in scene.parts}
    paints = sorted({(p.color, p.opacity) for p in scene.parts} | {(style.link_color(0), 1.0)})
    if model is not None:
        root = ET.fromstring(write_mjcf(model))
        _colour_bodies(root, {link.name: paint.get(link.source) for link in model.links})
    else:
        root = ET.Element("mujoco", model=scene.title)
        _static_meshes(root, scene)
    _decorate(root, scene, view, width, height, paints)
    _draw_segments(root, scene.segments())
    ET.indent(root, space="  ")
    return ET.tostring(root, encoding="unicode")


def _material_name(color: style.RGB, opacity: float = 1.0) -> str:
    return f"paint_{style.hex_color(color)[1:]}_{round(100 * opacity)}"


def _colour_bodies(
    root: ET.Element, body_paint: Mapping[str, tuple[style.RGB, float] | None]
) -> None:
    for body in root.iter("body"):
        color, opacity = body_paint.get(body.get("name", "")) or (style.link_color(0), 1.0)
        for geom in body.findall("geom"):
            geom.set("material", _material_name(color, opacity))


def _static_meshes(root: ET.Element, scene: Scene) -> None:
    asset = ET.SubElement(root, "asset")
    world = ET.SubElement(root, "worldbody")
    for i, part in enumerate(scene.parts):
        name = f"part{i}"
        ET.SubElement(
            asset,
            "mesh",
            name=name,
            vertex=vec(part.vertices.reshape(-1)),
            face=" ".join(str(int(k)) for k in part.faces.reshape(-1)),
        )
        ET.SubElement(
            world, "geom", type="mesh", mesh=name, material=_material_name(part.color, part.opacity)
        )


def _child(root: ET.Element, tag: str, first: bool = False) -> ET.Element:
    """The element ``tag`` under root, created (at the front, if ``first``) when missing."""
    el = root.find(tag)
    if el is None:
        el = ET.Element(tag)
        if first:
            root.insert(0, el)
        else:
            root.append(el)
    return el


def _decorate(
    root: ET.Element,
    scene: Scene,
    view: View,
    width: int,
    height: int,
    paints: list[tuple[style.RGB, float]],
) -> None:
    visual = _child(root, "visual", first=True)
    ET.SubElement(visual, "global", offwidth=str(width), offheight=str(height), fovy=num(view.fovy))
    ET.SubElement(visual, "quality", shadowsize="4096", offsamples="8")
    ET.SubElement(
        visual, "headlight", ambient="0.38 0.38 0.38", diffuse="0.42 0.42 0.42", specular="0 0 0"
    )
    # znear/zfar are fractions of the model's extent: set the extent to the scene's own size
    ET.SubElement(visual, "map", znear="0.1", zfar="12", shadowclip="1.2")
    lo, hi = scene.bounds()
    extent = max(float(np.linalg.norm(hi - lo)), view.distance / 4, 1e-3)
    stat = ET.Element("statistic", extent=num(extent), center=vec((lo + hi) / 2))
    root.insert(1, stat)
    asset = _child(root, "asset")
    bg = vec(style.BACKGROUND)
    ET.SubElement(
        asset,
        "texture",
        name="sky",
        type="skybox",
        builtin="flat",
        rgb1=bg,
        rgb2=bg,
        width="16",
        height="16",
    )
    for color, opacity in paints:
        ET.SubElement(
            asset,
            "material",
            name=_material_name(color, opacity),
            rgba=vec((*color, opacity)),
            specular="0.25",
            shininess="0.4",
        )
    world = _child(root, "worldbody")
    right, up, back = view.basis()
    key = -(0.9 * up - 0.6 * right + 0.7 * back)  # from the upper left, in front of the object
    fill = -(0.2 * up + 0.9 * right + 0.6 * back)  # from the right, dimmer
    ET.SubElement(
        world,
        "light",
        name="key",
        directional="true",
        castshadow="true",
        pos=vec(np.asarray(view.target) - key * extent),
        dir=vec(key / np.linalg.norm(key)),
        diffuse="0.55 0.55 0.55",
        specular="0.25 0.25 0.25",
    )
    ET.SubElement(
        world,
        "light",
        name="fill",
        directional="true",
        castshadow="false",
        pos=vec(np.asarray(view.target) - fill * extent),
        dir=vec(fill / np.linalg.norm(fill)),
        diffuse="0.22 0.22 0.24",
        specular="0 0 0",
    )
    ET.SubElement(
        world,
        "camera",
        name=CAMERA,
        pos=vec(view.eye),
        xyaxes=vec((*right, *up)),
        fovy=num(view.fovy),
    )


HEAD_LENGTH = 5.0  # arrow head length and radius, in shaft radii
HEAD_RADIUS = 2.4
CONE_SIDES = 16


def _draw_segments(root: ET.Element, segments: tuple[Segment, ...]) -> None:
    asset = _child(root, "asset")
    world = _child(root, "worldbody")
    for color in dict.fromkeys(s.color for s in segments):
        ET.SubElement(
            asset,
            "material",
            name="deco_" + style.hex_color(color)[1:],
            rgba=vec((*color, 1.0)),
            emission="0.45",
            specular="0.1",
        )
    for i, seg in enumerate(segments):
        start, end = np.array(seg.start), np.array(seg.end)
        length = float(np.linalg.norm(end - start))
        if length < DEGENERATE:
            continue
        d = (end - start) / length
        material = "deco_" + style.hex_color(seg.color)[1:]
        touch = {"contype": "0", "conaffinity": "0", "material": material}
        head = min(HEAD_LENGTH * seg.radius, 0.5 * length) if seg.head else 0.0
        shaft_end = end - head * d
        kind = "cylinder" if seg.head else "capsule"
        ET.SubElement(
            world,
            "geom",
            {
                "name": f"{DECORATION}{i}",
                "type": kind,
                "fromto": vec((*start, *shaft_end)),
                "size": num(seg.radius),
                **touch,
            },
        )
        if seg.head:
            ET.SubElement(asset, "mesh", {"name": f"head{i}", **_cone(shaft_end, end, seg.radius)})
            head_geom = {"name": f"{DECORATION}{i}_head", "type": "mesh", "mesh": f"head{i}"}
            ET.SubElement(world, "geom", {**head_geom, **touch})


def _cone(base: np.ndarray, tip: np.ndarray, shaft_radius: float) -> dict[str, str]:
    """An arrow head's vertices (world frame) and faces, as MJCF mesh attributes."""
    axis = (tip - base) / np.linalg.norm(tip - base)
    helper = np.array([1.0, 0.0, 0.0]) if abs(axis[0]) < 0.9 else np.array([0.0, 1.0, 0.0])
    u = np.cross(axis, helper)
    u /= np.linalg.norm(u)
    v = np.cross(axis, u)
    t = np.linspace(0, 2 * np.pi, CONE_SIDES, endpoint=False)
    r = HEAD_RADIUS * shaft_radius
    ring = base + r * (np.outer(np.cos(t), u) + np.outer(np.sin(t), v))
    verts = np.vstack([ring, tip, base])
    n, apex, centre = CONE_SIDES, CONE_SIDES, CONE_SIDES + 1
    faces = [(k, (k + 1) % n, apex) for k in range(n)]
    faces += [((k + 1) % n, k, centre) for k in range(n)]
    return {
        "vertex": vec(verts.reshape(-1)),
        "face": " ".join(str(i) for f in faces for i in f),
    }

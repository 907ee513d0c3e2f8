"""Mesh files of an instance (OBJ, STL, GLB) in the world frame, at its joint values.

OBJ and STL hold one mesh: the whole instance (``inst.mesh()``) or one link
(``inst.link_mesh(name)``). GLB keeps the links apart: one named node per link, coloured as in
the pictures (``grace_dsl.render.style``), so a viewer can tell the door from the body.
"""

from __future__ import annotations

from pathlib import Path
from typing import TYPE_CHECKING

import numpy as np
import trimesh

from grace_dsl.export.common import output_file
from grace_dsl.runtime.errors import GraceError

if TYPE_CHECKING:
    from grace_dsl.runtime.instance import Instance

MESH_FORMATS = ("obj", "stl", "glb")


class MeshExportError(GraceError):
    """A mesh that cannot be written: an unknown format, or nothing to write."""


def instance_meshes(
    inst: Instance, link: str | None = None, resolution: int = 64
) -> dict[str, trimesh.Trimesh]:
    """The non-empty meshes per link (only ``link`` when given), world frame, joint values."""
    links = [link] if link is not None else list(inst.links)
    out = {name: inst.link_mesh(name, resolution=resolution) for name in links}
    out = {name: mesh for name, mesh in out.items() if len(mesh.faces)}
    if not out:
        what = f"link {link}" if link is not None else inst.concept.name
        raise MeshExportError(f"{what} has no shapes: there is no mesh to write")
    return out


def _coloured(inst: Instance, meshes: dict[str, trimesh.Trimesh]) -> trimesh.Scene:
    from grace_dsl.render.style import link_color

    scene = trimesh.Scene()
    links = list(inst.concept.links)
    for name, mesh in meshes.items():
        rgba = [*(round(255 * c) for c in link_color(links.index(name))), 255]
        material = trimesh.visual.material.PBRMaterial(
            name=name, baseColorFactor=rgba, metallicFactor=0.0, roughnessFactor=0.8
        )
        part = mesh.copy()
        part.visual = trimesh.visual.TextureVisuals(material=material)
        scene.add_geometry(part, node_name=name, geom_name=name)
    return scene


def write_instance_mesh(
    inst: Instance,
    path: str | Path,
    fmt: str | None = None,
    link: str | None = None,
    resolution: int = 64,
) -> trimesh.Trimesh:
    """Write the instance (or one link) to ``path`` as ``fmt`` (default: the file's suffix);
    returns the mesh written: the instance's one closed solid (``inst.mesh()``) or the link's;
    GLB keeps the links apart."""
    target = output_file(path, f".{fmt or 'obj'}")
    kind = (fmt or target.suffix.lstrip(".")).lower()
    if kind not in MESH_FORMATS:
        raise MeshExportError(
            f"cannot write {target.name!r} as a mesh: use one of " + ", ".join(MESH_FORMATS)
        )
    meshes = instance_meshes(inst, link, resolution)
    merged = inst.mesh(resolution) if link is None else meshes[link]
    target.parent.mkdir(parents=True, exist_ok=True)
    if kind == "glb":
        target.write_bytes(_coloured(inst, meshes).export(file_type="glb"))
    elif kind == "obj":
        merged.export(target, file_type="obj", digits=12)  # text: keep ~1e-12 m, not 1e-8
    else:
        merged.export(target, file_type=kind)  # binary STL: float32, like GLB
    return merged


def mesh_summary(mesh: trimesh.Trimesh) -> dict[str, object]:
    """Numbers a user checks a mesh by: size, volume, bounds (SI)."""
    return {
        "vertices": len(mesh.vertices),
        "faces": len(mesh.faces),
        "volume": float(mesh.volume),
        "bounds": np.asarray(mesh.bounds, dtype=float).tolist(),
    }

"""Pictures of concept instances: a scene description, MuJoCo PNGs and a self-contained HTML viewer.

``describe(inst)`` builds the :class:`Scene` (meshes per link, grasp frames, forces, joint axes);
``write_png`` (MuJoCo, offscreen) and ``write_html`` (a page with its own WebGL/Canvas viewer)
draw it. MuJoCo is imported only when a PNG is made.
"""

from grace_dsl.render.scene import (
    Force,
    GraspFrame,
    JointAxis,
    MeshPart,
    Scene,
    Segment,
    describe,
    primitive_scene,
)

__all__ = [
    "Force",
    "GraspFrame",
    "JointAxis",
    "MeshPart",
    "Scene",
    "Segment",
    "describe",
    "primitive_scene",
]

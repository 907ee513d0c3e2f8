"""Export an instance to simulators: URDF (Pinocchio, PyBullet, ROS) and MJCF (MuJoCo).

The instance's parameters are baked into the geometry; its joints stay joints, and its joint
values become the initial state where the format has one (MJCF keyframe ``instance``; URDF has
none). See ``model.py`` for how frames are placed at the joint origins.
"""

from grace_dsl.export.mjcf import export_mjcf, write_mjcf
from grace_dsl.export.model import ExportModel, ExportOptions, build_model
from grace_dsl.export.urdf import export_urdf, write_urdf

__all__ = [
    "ExportModel",
    "ExportOptions",
    "build_model",
    "export_mjcf",
    "export_urdf",
    "write_mjcf",
    "write_urdf",
]

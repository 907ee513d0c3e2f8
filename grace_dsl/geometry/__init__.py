"""Primitive assets: meshes (trimesh), exact signed distances (numpy and CasADi), surface samples.

Every function takes a primitive name from ``concepts/primitives.eac`` and a dict of its
parameters in SI units (missing ones take the defaults); see docs/primitives.md for the frames.
"""

from grace_dsl.geometry.errors import GeometryError
from grace_dsl.geometry.mesh import DEFAULT_RESOLUTION, primitive_mesh
from grace_dsl.geometry.pieces import ConvexPiece, convex_pieces
from grace_dsl.geometry.primitives import PRIMITIVES, PrimitiveSpec, default_params, validate
from grace_dsl.geometry.props import affordances, bounds, volume
from grace_dsl.geometry.sample import sample_surface, surface_area
from grace_dsl.geometry.sdf import primitive_sdf, primitive_sdf_casadi

__all__ = [
    "DEFAULT_RESOLUTION",
    "PRIMITIVES",
    "ConvexPiece",
    "GeometryError",
    "PrimitiveSpec",
    "affordances",
    "bounds",
    "convex_pieces",
    "default_params",
    "primitive_mesh",
    "primitive_sdf",
    "primitive_sdf_casadi",
    "sample_surface",
    "surface_area",
    "validate",
    "volume",
]

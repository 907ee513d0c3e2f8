"""GRACE-EAC: executable analytic concepts for precise robot manipulation.

import grace_dsl as eac
lib = eac.load_library()
inst = lib["CurveHandle"].instantiate(radian=1.8)
inst.grasp("pull", theta=0.1)
"""

from grace_dsl.runtime.errors import (
    CompileError,
    EvaluationError,
    GraceError,
    ParameterError,
    RequirementError,
    UnknownNameError,
)
from grace_dsl.runtime.gripper import Gripper
from grace_dsl.runtime.instance import Instance
from grace_dsl.runtime.library import Concept, Library, compile_paths, load_artifact, load_library
from grace_dsl.runtime.manipulation import Option

__version__ = "0.1.0"

__all__ = [
    "CompileError",
    "Concept",
    "EvaluationError",
    "GraceError",
    "Gripper",
    "Instance",
    "Library",
    "Option",
    "ParameterError",
    "RequirementError",
    "UnknownNameError",
    "compile_paths",
    "load_artifact",
    "load_library",
]

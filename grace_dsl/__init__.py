"""GRACE-EAC: executable analytic concepts for precise robot manipulation.

import grace_dsl as eac
lib = eac.load_library()
inst = lib["CurveHandle"].instantiate(radian=1.8)
inst.grasp("pull", theta=0.1)
"""

from typing import TYPE_CHECKING

from grace_dsl.runtime.errors import (
    CompileError,
    EvaluationError,
    GraceError,
    GraspConditionError,
    ParameterError,
    RequirementError,
    UnknownNameError,
)
from grace_dsl.runtime.gripper import Gripper
from grace_dsl.runtime.instance import Instance
from grace_dsl.runtime.kinematics import JointAxes, Kinematics
from grace_dsl.runtime.library import Concept, Library, compile_paths, load_artifact, load_library
from grace_dsl.runtime.manipulation import Option

__version__ = "0.1.0"

if TYPE_CHECKING:  # what the lazy names below resolve to, for type checkers
    from grace_dsl.perception.estimate import estimate
    from grace_dsl.perception.types import Estimate
    from grace_dsl.robot.act import ActionPlan, ActionPlanningError, plan_action
    from grace_dsl.robot.choose import GraspChoice, choose_grasp
    from grace_dsl.robot.collision import collision_scene
    from grace_dsl.robot.grasp_ik import GraspIKResult, solve_grasp_ik
    from grace_dsl.robot.ik import IKOptions, IKResult, solve_ik
    from grace_dsl.robot.model import Robot
    from grace_dsl.robot.timing import time_optimal

# The robot layer loads Pinocchio's robot models and OSQP: imported on first use, so that
# `import grace_dsl` (and every `eacc` command) stays quick.
_ROBOT = {
    "Robot": "grace_dsl.robot.model",
    "IKResult": "grace_dsl.robot.ik",
    "IKOptions": "grace_dsl.robot.ik",
    "solve_ik": "grace_dsl.robot.ik",
    "GraspIKResult": "grace_dsl.robot.grasp_ik",
    "solve_grasp_ik": "grace_dsl.robot.grasp_ik",
    "GraspChoice": "grace_dsl.robot.choose",
    "choose_grasp": "grace_dsl.robot.choose",
    "collision_scene": "grace_dsl.robot.collision",
    "ActionPlan": "grace_dsl.robot.act",
    "plan_action": "grace_dsl.robot.act",
    "ActionPlanningError": "grace_dsl.robot.act",
    "time_optimal": "grace_dsl.robot.timing",
    "estimate": "grace_dsl.perception.estimate",
    "Estimate": "grace_dsl.perception.types",
}


def __getattr__(name: str) -> object:
    import importlib

    if name in _ROBOT:
        return getattr(importlib.import_module(_ROBOT[name]), name)
    if name == "agent":  # eac.agent.parse(...): task parsing, imported on first use
        return importlib.import_module("grace_dsl.agent")
    raise AttributeError(f"module 'grace_dsl' has no attribute {name!r}")


__all__ = [
    "ActionPlan",
    "Estimate",
    "estimate",
    "ActionPlanningError",
    "GraspChoice",
    "GraspIKResult",
    "IKOptions",
    "IKResult",
    "Robot",
    "choose_grasp",
    "collision_scene",
    "plan_action",
    "solve_grasp_ik",
    "solve_ik",
    "time_optimal",
    "CompileError",
    "Concept",
    "EvaluationError",
    "GraceError",
    "GraspConditionError",
    "Gripper",
    "Instance",
    "JointAxes",
    "Kinematics",
    "Library",
    "Option",
    "ParameterError",
    "RequirementError",
    "UnknownNameError",
    "compile_paths",
    "load_artifact",
    "load_library",
]

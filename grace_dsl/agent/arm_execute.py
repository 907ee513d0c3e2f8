"""The agent's loop with the full Panda: each sub-task planned from a base beside its object.

``Executor`` (``grace_dsl.agent.execute``) carries a plan out with the flying hand; ``ArmExecutor``
is the same loop (parameters from the ``ParamSource``, measured joint values, verification,
bounded retries) with the arm of ``grace_dsl.sim.arm`` in a room of several objects
(``grace_dsl.sim.arm_multi``). Per attempt:

1. the base is placed beside the target object: ``PLACE_REACH`` in front of the action's grasps
   and ``placement.HEIGHT`` below them, facing the object's front, stepped back while the arm's
   home posture would touch the object or anything else in the room;
2. the robot layer plans the whole action from there (``placement.plan_placed``: grasp postures
   by IK, collision-checked insert, interaction and retreat, an OMPL approach; other base
   placements when that one cannot), checking collisions against the target AND every other
   object of the scene at its measured joint values (``obstacles``), with only the manipulation
   functions not tried yet (``grasps``); an open the arm can plan only part of the way is
   replanned to ``REPLAN_AT`` of what it reached when that still meets the condition;
3. the world teleports the base there (the drive between objects is not simulated) and executes
   the plan on the persistent world, so what earlier steps left is what this one finds.

A planning failure is ``ik_failure`` (no grasp posture reachable, or none from which the action
can be tracked; ``no_feasible_grasp`` when ``inst.rank`` finds no option for the hand) and ends
the sub-task: the planner has already tried every option not yet executed from every placement.
An executed attempt that leaves the condition unmet has the flying hand's reasons (``collision``
when the arm was stopped on its way in, ``slip``, ``timeout``, ...) and the next attempt plans
with the next-ranked options.
"""

from __future__ import annotations

import math
from collections.abc import Mapping
from functools import lru_cache
from typing import TYPE_CHECKING, Any

import numpy as np

from grace_dsl.agent.execute import (
    MAX_ATTEMPTS,
    SECONDS,
    Attempt,
    Executor,
    ParamSource,
    _why,
    against_action,
    aim,
)
from grace_dsl.agent.plan import Condition, SceneSpec, SubTask, Target
from grace_dsl.runtime.errors import GraceError
from grace_dsl.sim.arm_multi import ArmMultiWorld, base_yaw
from grace_dsl.sim.protocol import TaskAction

if TYPE_CHECKING:
    from grace_dsl.robot.act import ActionPlan
    from grace_dsl.robot.model import Robot
    from grace_dsl.runtime.instance import Instance
    from grace_dsl.runtime.library import Library
    from grace_dsl.sim.camera import Camera

PLACE_REACH = 0.60  # m in front of the grasps' centre the base stands (placement.REACH)
OPEN_TO = 0.7  # "open" is planned to this fraction of the range (the arm episode's choice)
REPLAN_AT = 0.95  # a partial open is replanned to this much of how far the arm got
PLACEMENTS = 6  # base placements the planner may try per attempt (as the arm episode)


@lru_cache(maxsize=1)
def panda() -> Robot:
    """The robot layer's Panda, loaded once per process."""
    from grace_dsl.robot.model import Robot

    return Robot.panda()


class ArmExecutor(Executor):
    """``Executor`` with the full Panda on a base placed per sub-task (module docstring)."""

    def __init__(
        self,
        scene: SceneSpec,
        library: Library | Mapping[str, Any],
        params: ParamSource | None = None,
        max_attempts: int = MAX_ATTEMPTS,
        seconds: float = SECONDS,
        camera: Camera | None = None,
        seed: int = 0,
    ):
        self.robot = panda()
        self.seed = seed
        super().__init__(
            scene,
            library,
            self.robot.gripper,
            params=params,
            max_attempts=max_attempts,
            seconds=seconds,
            camera=camera,
        )

    def _world(self, truth: list[tuple[str, Instance]], camera: Camera | None) -> ArmMultiWorld:
        return ArmMultiWorld(truth, self.gripper, camera=camera)

    def _attempt(self, sub: SubTask, sign: float, tried: list[str]) -> Attempt:
        inst = self.belief(sub.object)
        q0 = self.world.q(sub.object, sub.joint)
        lo, hi = inst.joint_limits()[sub.joint]
        goal = arm_aim(sub.target, sub.condition, q0, lo, hi, sign)
        wrong_way = against_action(sub, q0, goal, sign)
        if wrong_way is not None:
            return wrong_way
        arm = tuple(float(v) for v in self.world.arm_q())
        feasible = [o.grasp for o in inst.rank(sub.action, gripper=self.gripper) if o.feasible]
        if not feasible:
            why = f"no manipulation function of {sub.action} is feasible for the Panda hand"
            return Attempt(
                "", q0, q0, goal, False, "no_feasible_grasp", why, arm_before=arm, arm_after=arm
            )
        try:
            plan = self._plan(sub, inst, goal, sign, [g for g in feasible if g not in tried])
        except GraceError as exc:  # no grasp posture reachable, or no path from one
            return Attempt(
                "", q0, q0, goal, False, "ik_failure", str(exc), arm_before=arm, arm_after=arm
            )
        option = plan.choice.option
        tried.append(option.grasp)
        task = TaskAction(sub.action, sub.joint, sign)
        drive = plan.to if sign > 0 else goal
        act = self.world.act(sub.object, task, plan, drive, self.seconds, inst=inst)
        verified = sub.condition.holds(self.measured(sub.condition.object, sub.condition.joint))
        reason, detail = ("", "") if verified else _why(act.outcome, q0, act.q_after, sign)
        b = act.base
        where = (float(b[0, 3]), float(b[1, 3]), float(b[2, 3]), base_yaw(b))
        return Attempt(
            f"{option.grasp} ({option.mode})",
            q0,
            act.q_after,
            drive,
            verified,
            reason,
            detail,
            act.sim_seconds,
            base=tuple(round(v, 4) for v in where),
            arm_before=act.arm_before,
            arm_after=act.arm_after,
        )

    def _plan(
        self, sub: SubTask, inst: Instance, goal: float | None, sign: float, fresh: list[str]
    ) -> ActionPlan:
        """The robot layer's plan for the sub-task from a base beside the object, collision
        checked against the whole room, with the options ``fresh`` (not tried yet; all of them
        when empty); a partial open replanned as far as the arm reaches when that is enough."""
        from grace_dsl.robot.act import ActionPlanningError
        from grace_dsl.robot.placement import plan_placed

        others = [self.world.instance(n) for n in self.objects if n != sub.object]
        base = stand_beside(self.robot, inst, sub.action, others)
        lo = inst.joint_limits()[sub.joint][0]
        to = goal if goal is not None else lo
        kwargs: dict[str, Any] = {
            "base": base,
            "seed": self.seed,
            "count": PLACEMENTS,
            "obstacles": others,
            "grasps": fresh or None,
        }
        try:
            return plan_placed(self.robot, inst, sub.action, to, **kwargs).plan
        except ActionPlanningError as exc:
            start = float(inst.joints[sub.joint])
            if sign < 0 or exc.value is None:
                raise
            partial = start + REPLAN_AT * (float(exc.value) - start)
            if not sub.condition.holds(partial):
                raise
            return plan_placed(self.robot, inst, sub.action, partial, **kwargs).plan


def arm_aim(
    target: Target, cond: Condition, q0: float, lo: float, hi: float, sign: float
) -> float | None:
    """``execute.aim`` for the arm: "open" aims at ``OPEN_TO`` of the range, not the flying
    hand's 0.9 (the further a door swings, the sooner the arm's workspace ends)."""
    goal = aim(target, cond, q0, lo, hi, sign)
    if target.kind == "open" and goal is not None:
        want = lo + OPEN_TO * (hi - lo)
        if cond.lo <= want <= cond.hi:
            return want
    return goal


def stand_beside(robot: Robot, inst: Instance, action: str, others: list[Instance]) -> np.ndarray:
    """The base's world pose for ``action`` on ``inst``: ``PLACE_REACH`` in front of the
    action's grasps (along the object's front, concept +z, flattened onto the floor), their
    height less ``placement.HEIGHT``, facing them; stepped back while the home posture would
    touch the object or any of ``others``."""
    from grace_dsl.robot.collision import collision_scene
    from grace_dsl.robot.placement import (
        HEIGHT,
        MAX_STEPS_BACK,
        STEP_BACK,
        _grasp_centre,
        base_pose,
    )

    centre = _grasp_centre(inst, action)
    front = np.asarray(inst.pose[:3, 2], float).copy()
    front[2] = 0.0
    front /= max(float(np.linalg.norm(front)), 1e-9)
    x, y = centre[:2] + PLACE_REACH * front[:2]
    base = base_pose(float(x), float(y), math.atan2(-front[1], -front[0]))
    base[2, 3] = float(centre[2]) - HEIGHT
    for _ in range(MAX_STEPS_BACK):
        scene = collision_scene(robot, inst, base=base, obstacles=others)
        if not scene.collides(robot.home):
            break
        base[:2, 3] += STEP_BACK * front[:2]
    return base

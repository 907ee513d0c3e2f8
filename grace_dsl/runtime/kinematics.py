"""The kinematics of a concept at fixed parameters: link poses, joint axes, grasp poses and their
Jacobians, through the compiled (native where possible) functions of the concept.

Why a facade: export, render, verify and robot IK all need the same few queries, and reaching
them by key strings (``concept.function("link", name)``) spreads untyped calls, shape juggling and
name checks over the package. Here each query has a name, validated arguments and typed float64
results.

Frames. Every pose and vector is in the *world* frame of the facade's ``pose`` (world <- concept);
``Kinematics.of(inst)`` takes the instance's pose, and with ``pose=None`` world is the concept
frame.

Jacobians. ``grasp_jacobian`` and ``link_jacobian`` return 6 x n matrices with rows
``[v; w]``: ``v`` the velocity of the frame's *origin* and ``w`` its angular velocity, both along
the world axes, per unit change of each variable (Pinocchio's ``LOCAL_WORLD_ALIGNED``
convention). Columns are the moving joints (``moving_joints`` order), then for a grasp its free
parameters (the grasp's ``free`` order). A first-order move ``dx`` takes a frame ``T`` to
``T' = [exp([w dx]x) R | t + v dx]``. The derivatives are exact: CasADi differentiates the same
graph that computes the pose, at compile time.

Batching: wherever ``q`` (or ``g``) may be given, an (N, n) array evaluates N configurations in
one native call, and the result gets a leading axis N.
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from dataclasses import dataclass, replace
from typing import TYPE_CHECKING, Any

import numpy as np
import numpy.typing as npt

from grace_dsl.compiler.native import Evaluator, Outputs
from grace_dsl.runtime.concept import suggest
from grace_dsl.runtime.errors import ParameterError, UnknownNameError

if TYPE_CHECKING:
    from grace_dsl.runtime.instance import Instance
    from grace_dsl.runtime.library import Concept

FloatArray = npt.NDArray[np.float64]

__all__ = ["JointAxes", "Kinematics"]


@dataclass(frozen=True)
class JointAxes:
    """The moving joints' axes in the world: ``axes`` (…, J, 3) unit vectors that carry the
    opening sense (a revolute joint opens right-handed about its axis, a prismatic one along
    it) and ``origins`` (…, J, 3) points on them; ``names`` in the same order."""

    names: tuple[str, ...]
    axes: FloatArray
    origins: FloatArray


@dataclass(frozen=True, eq=False)
class Kinematics:
    """A concept's kinematics at parameter vector ``p``, placed at ``pose`` (world <- concept);
    ``q`` is the default joint vector (the instance's, or the closed state)."""

    concept: Concept
    p: FloatArray
    pose: FloatArray
    q: FloatArray

    @staticmethod
    def of(source: Instance | Concept, pose: Any = None) -> Kinematics:
        """The kinematics of an instance (its parameters, pose and joint values), or of a
        concept at its default parameters, closed, at ``pose`` (default: the concept frame)."""
        from grace_dsl.runtime.instance import Instance

        if isinstance(source, Instance):
            world = source.pose if pose is None else _world_pose(pose)
            return Kinematics(source.concept, source.p, world, source.q)
        p = source.pack()
        return Kinematics(source, p, _world_pose(pose), np.zeros(len(source.moving_joints)))

    def in_concept_frame(self) -> Kinematics:
        """The same kinematics with world = the concept frame (what exported models use)."""
        return replace(self, pose=np.eye(4))

    # -- structure
    @property
    def joints(self) -> tuple[str, ...]:
        """The moving joints: the columns of ``q`` and of the Jacobians' joint part."""
        return tuple(self.concept.moving_joints)

    @property
    def links(self) -> tuple[str, ...]:
        """Every link, in the order of :meth:`link_poses`."""
        return tuple(self.concept.links)

    def free_parameters(self, grasp: str) -> tuple[str, ...]:
        """The free parameters of ``grasp``: the columns of ``g``."""
        return tuple(f["name"] for f in self._grasp(grasp)["free"])

    def joint_limits(self) -> tuple[FloatArray, FloatArray]:
        """Lower and upper joint limits (J,), +-inf where a joint turns freely."""
        lo, hi = _outputs(self._fn("joint_limits")(self.p), 2)
        return lo.reshape(-1), hi.reshape(-1)

    def grasp_range(self, grasp: str) -> tuple[FloatArray, FloatArray, FloatArray]:
        """Lower bounds, upper bounds and defaults (G,) of the free parameters of ``grasp``."""
        self._grasp(grasp)
        lo, hi, default = _outputs(self._fn("grasp_range", grasp)(self.p), 3)
        return lo.reshape(-1), hi.reshape(-1), default.reshape(-1)

    # -- poses
    def link_pose(self, link: str, q: Any = None) -> FloatArray:
        """The world pose (4, 4) of ``link``; (N, 4, 4) for a batch of joint vectors."""
        self._link(link)
        qs, batched = self._joints(q)
        return self._place(self._eval(self._fn("link", link), batched, self.p, qs)[0])

    def link_poses(self, q: Any = None) -> FloatArray:
        """The world poses of every link (L, 4, 4), in :attr:`links` order; for a batch of
        joint vectors (N, J), (N, L, 4, 4)."""
        qs, batched = self._joints(q)
        poses = [self._eval(self._fn("link", link), batched, self.p, qs)[0] for link in self.links]
        return self._place(np.stack(poses, axis=-3))

    def joint_axes(self, q: Any = None) -> JointAxes:
        """The moving joints' axes (unit, opening sense) and points on them, in the world."""
        qs, batched = self._joints(q)
        axes, origins = self._eval(self._fn("joint_axes"), batched, self.p, qs)
        n = qs.shape[0] if batched else None
        shape = (-1, 3) if n is None else (n, -1, 3)
        axes, origins = axes.reshape(shape), origins.reshape(shape)
        axes = axes / np.linalg.norm(axes, axis=-1, keepdims=True)
        rot, origin = self.pose[:3, :3], self.pose[:3, 3]
        return JointAxes(self.joints, axes @ rot.T, origins @ rot.T + origin)

    def grasp_pose(self, grasp: str, q: Any = None, g: Any = None) -> FloatArray:
        """The world pose (4, 4) of ``grasp`` at joints ``q`` and free parameters ``g`` (a
        vector in :meth:`free_parameters` order or a mapping; default the grasp's defaults).

        A ``symmetric`` grasp is returned as compiled, not spun to a reference orientation
        (``Instance.grasp`` does that). Ranges of q and g are not enforced: solvers step
        outside them and bound the variables themselves (see :meth:`grasp_range`).
        """
        self._grasp(grasp)
        qs, gs, batched = self._joints_and_free(grasp, q, g)
        return self._place(self._eval(self._fn("grasp", grasp), batched, self.p, qs, gs)[0])

    # -- Jacobians
    def grasp_jacobian(self, grasp: str, q: Any = None, g: Any = None) -> FloatArray:
        """The twist Jacobian (6, J + G) of the grasp frame in joints then free parameters (see
        the module docstring for the convention); (N, 6, J + G) for a batch."""
        return self.grasp_pose_jacobian(grasp, q, g)[1]

    def grasp_pose_jacobian(
        self, grasp: str, q: Any = None, g: Any = None
    ) -> tuple[FloatArray, FloatArray]:
        """The grasp's world pose and its twist Jacobian from one native call (what an IK
        iteration needs)."""
        self._grasp(grasp)
        qs, gs, batched = self._joints_and_free(grasp, q, g)
        pose, jac = self._eval(self._fn("grasp_jac", grasp), batched, self.p, qs, gs)
        return self._place(pose), self._rotate(jac)

    def link_jacobian(self, link: str, q: Any = None) -> FloatArray:
        """The twist Jacobian (6, J) of ``link``'s frame in the joints; (N, 6, J) for a batch."""
        return self.link_pose_jacobian(link, q)[1]

    def link_pose_jacobian(self, link: str, q: Any = None) -> tuple[FloatArray, FloatArray]:
        """``link``'s world pose and its twist Jacobian from one native call."""
        self._link(link)
        qs, batched = self._joints(q)
        pose, jac = self._eval(self._fn("link_jac", link), batched, self.p, qs)
        return self._place(pose), self._rotate(jac)

    # -- helpers
    def _fn(self, kind: str, name: str = "") -> Evaluator:
        return self.concept.function(kind, name)

    def _eval(self, fn: Evaluator, batched: bool, *args: FloatArray) -> tuple[FloatArray, ...]:
        if batched:
            return _outputs(fn.batch(*args), None)
        return _outputs(fn(*args), None)

    def _place(self, local: FloatArray) -> FloatArray:
        """World poses ``M @ T`` of concept-frame poses (..., 4, 4)."""
        return np.asarray(self.pose @ local, dtype=np.float64)

    def _rotate(self, jac: FloatArray) -> FloatArray:
        """A twist Jacobian (..., 6, n) from concept axes to world axes: both halves by R."""
        rot = self.pose[:3, :3]
        out = np.empty_like(jac)
        out[..., :3, :] = rot @ jac[..., :3, :]
        out[..., 3:, :] = rot @ jac[..., 3:, :]
        return out

    def _link(self, link: str) -> None:
        if link not in self.concept.links:
            raise UnknownNameError(
                f"{self.concept.name} has no link {link!r}" + suggest(link, self.concept.links)
            )

    def _grasp(self, grasp: str) -> Mapping[str, Any]:
        try:
            return self.concept.grasps[grasp]
        except KeyError:
            raise UnknownNameError(
                f"{self.concept.name} has no grasp {grasp!r}"
                + suggest(grasp, self.concept.grasps or ["(none)"])
            ) from None

    def _joints(self, q: Any) -> tuple[FloatArray, bool]:
        """``q`` as (J,) or a batch (N, J), and whether it is a batch."""
        if q is None:
            return self.q, False
        if isinstance(q, Mapping):
            return self._vector_from_mapping(
                f"{self.concept.name} has no moving joint", self.joints, q, self.q
            ), False
        return _vector_or_batch("q", q, len(self.joints), "the moving joints " + _list(self.joints))

    def _joints_and_free(self, grasp: str, q: Any, g: Any) -> tuple[FloatArray, FloatArray, bool]:
        qs, q_batched = self._joints(q)
        names = self.free_parameters(grasp)
        if g is None or isinstance(g, Mapping):
            default = self.grasp_range(grasp)[2]
            what = f"grasp {grasp} has no free parameter"
            gs = default if g is None else self._vector_from_mapping(what, names, g, default)
            return qs, gs, q_batched
        gs, g_batched = _vector_or_batch("g", g, len(names), f"{grasp}'s free parameters")
        if q_batched and g_batched and qs.shape[0] != gs.shape[0]:
            raise ParameterError(
                f"q and g hold different numbers of configurations ({qs.shape[0]} and "
                f"{gs.shape[0]})"
            )
        return qs, gs, q_batched or g_batched

    def _vector_from_mapping(
        self, what: str, names: Sequence[str], values: Mapping[str, Any], default: FloatArray
    ) -> FloatArray:
        """``default`` with the entries named in ``values`` replaced; an unknown name raises
        ``what`` followed by the name."""
        out = np.array(default, dtype=np.float64)
        for key, value in values.items():
            if key not in names:
                raise UnknownNameError(
                    f"{what} {key!r}" + suggest(str(key), list(names) or ["(none)"])
                )
            out[list(names).index(key)] = _number(key, value)
        return out


def _world_pose(value: Any) -> FloatArray:
    """A validated rigid 4x4 pose; None is the identity (world = concept frame)."""
    from grace_dsl.runtime.instance import rigid_problem

    if value is None:
        return np.eye(4)
    try:
        m = np.asarray(value, dtype=np.float64)
    except (TypeError, ValueError):
        raise ParameterError("pose must be a finite 4x4 matrix of numbers") from None
    if m.shape != (4, 4) or not np.all(np.isfinite(m)):
        raise ParameterError(f"pose must be a finite 4x4 matrix, got shape {m.shape}")
    problem = rigid_problem(m)
    if problem is not None:
        raise ParameterError(f"pose must be a rigid transform: {problem}")
    return m


def _list(names: Sequence[str]) -> str:
    return "(" + ", ".join(names) + ")" if names else "(none)"


def _number(name: str, value: Any) -> float:
    if isinstance(value, (bool, np.bool_, str, bytes)) or np.ndim(value) != 0:
        raise ParameterError(f"{name} takes one number (SI), not {value!r}")
    x = float(value)
    if not np.isfinite(x):
        raise ParameterError(f"{name} must be finite, not {x!r}")
    return x


def _vector_or_batch(name: str, value: Any, n: int, what: str) -> tuple[FloatArray, bool]:
    """A finite (n,) vector or (N, n) batch of them; anything else is a ParameterError."""
    try:
        arr = np.asarray(value, dtype=np.float64)
    except (TypeError, ValueError):
        raise ParameterError(f"{name} must be numbers: one value per {what}") from None
    if arr.ndim == 0 and n == 1:
        arr = arr.reshape(1)
    if arr.ndim not in (1, 2) or arr.shape[-1] != n:
        raise ParameterError(
            f"{name} must have shape ({n},) or (N, {n}): one value per {what}, got {arr.shape}"
        )
    if not np.all(np.isfinite(arr)):
        raise ParameterError(f"{name} must be finite, got {arr.tolist()!r}")
    return arr, arr.ndim == 2


def _outputs(result: Outputs, count: int | None) -> tuple[FloatArray, ...]:
    """An evaluator's result as a tuple of arrays (one output comes back bare)."""
    outs = result if isinstance(result, tuple) else (result,)
    if count is not None and len(outs) != count:
        raise RuntimeError(f"expected {count} outputs, got {len(outs)}")  # a compiler bug
    return outs

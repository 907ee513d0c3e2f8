"""An instantiated concept: grasp poses, force directions and joint motion in world coordinates.

World quantities follow the paper: ``G_world = M G_local`` and ``F_world = R F_local``, where M is
the instance pose and R its rotation.
"""

from __future__ import annotations

import math
from collections.abc import Mapping
from dataclasses import dataclass, field
from functools import lru_cache
from typing import TYPE_CHECKING, Any, cast

import numpy as np

from grace_dsl.runtime.concept import check_requirements, suggest
from grace_dsl.runtime.errors import ParameterError, UnknownNameError
from grace_dsl.runtime.symmetry import spin_to_reference

if TYPE_CHECKING:
    from grace_dsl.runtime.library import Concept


# Actions with these verbs turn the hand: along a joint, a grasp on its axis is twisted; with an
# explicit direction (`turn toward (0, 0, 1)`), the direction is the axis of the twist.
TWIST_VERBS = ("turn", "rotate")
_EYE3 = np.eye(3)
_LAST_ROW = np.array([0.0, 0.0, 0.0, 1.0])
_ORIGIN = np.zeros(3)  # any point: an explicit direction is the same everywhere


def _pose(value: Any) -> np.ndarray:
    """A validated rigid 4x4 pose (the identity for None); a float64 array passes unchanged."""
    if value is None:
        return np.eye(4)
    if (
        type(value) is np.ndarray
        and value.shape == (4, 4)
        and value.dtype == np.float64
        and _plainly_rigid(value.tolist())
    ):
        return value
    m = np.asarray(value, dtype=float)
    if m.shape != (4, 4) or not np.all(np.isfinite(m)):
        raise ParameterError(f"pose must be a finite 4x4 matrix, got shape {m.shape}")
    problem = rigid_problem(m)
    if problem is not None:
        raise ParameterError(f"pose must be a rigid transform: {problem}")
    return m


def rigid_problem(m: np.ndarray) -> str | None:
    """Why a finite 4x4 matrix is not a rigid transform (None when it is): the one test behind
    every pose the project accepts, from the API or the command line."""
    r = m[:3, :3]
    if np.abs(r.T @ r - _EYE3).max() > 1e-6 or np.abs(m[3] - _LAST_ROW).max() > 1e-12:
        return "its rotation must be orthonormal with determinant +1 and its last row 0 0 0 1"
    if np.linalg.det(r) < 0:
        return "its rotation is a mirror image (determinant -1; a rotation has determinant +1)"
    return None


def _joint_number(name: str, value: Any) -> float:
    """A joint value as a float (radians or metres); bools and text are mistakes."""
    if type(value) in (float, int, np.float64):
        return float(value)
    message = f"joint {name} takes one number (SI: rad or m), not {value!r}"
    if isinstance(value, (bool, np.bool_, str, bytes)) or np.ndim(value) != 0:
        raise ParameterError(message)
    try:
        return float(value)
    except (TypeError, ValueError):
        raise ParameterError(message) from None


def _count(name: str, value: Any, least: int) -> int:
    """A whole-number argument such as ``n`` or ``steps``, at least ``least``."""
    if isinstance(value, (bool, np.bool_)) or not isinstance(value, (int, np.integer)):
        raise ParameterError(f"{name} must be a whole number, not {value!r}")
    if value < least:
        raise ParameterError(f"{name} must be at least {least}, got {value}")
    return int(value)


def _points(points: Any) -> np.ndarray:
    """World points as a finite float (N, 3) array, or a ParameterError saying what is wrong."""
    try:
        pts = np.asarray(points, dtype=float)
    except (TypeError, ValueError):
        raise ParameterError("points must be numbers: a finite (N, 3) array") from None
    if pts.ndim != 2 or pts.shape[1] != 3:
        hint = "; for one point use [point]" if pts.shape == (3,) else ""
        raise ParameterError(f"points must be an (N, 3) array, got shape {pts.shape}{hint}")
    bad = ~np.isfinite(pts).all(axis=1)
    if bad.any():
        raise ParameterError(
            f"points must be finite: {int(bad.sum())} row(s) hold NaN or inf "
            f"(first at row {int(np.flatnonzero(bad)[0])})"
        )
    return pts


def _plainly_rigid(rows: list[list[float]]) -> bool:
    """The checks of ``_pose`` in plain floats (numpy's per-call overhead is 20x the work);
    False sends the pose through the numpy checks, which decide and explain."""
    (a, b, c, x), (d, e, f, y), (g, h, i, z), last = rows
    if last != [0.0, 0.0, 0.0, 1.0] or not math.isfinite(
        a + b + c + d + e + f + g + h + i + x + y + z
    ):
        return False
    tol = 1e-6  # columns orthonormal: R^T R = I, and no mirror: det R = +1
    return (
        abs(a * a + d * d + g * g - 1.0) <= tol
        and abs(b * b + e * e + h * h - 1.0) <= tol
        and abs(c * c + f * f + i * i - 1.0) <= tol
        and abs(a * b + d * e + g * h) <= tol
        and abs(a * c + d * f + g * i) <= tol
        and abs(b * c + e * f + h * i) <= tol
        and a * (e * i - f * h) - b * (d * i - f * g) + c * (d * h - e * g) > 0.0
    )


@dataclass(frozen=True)
class Instance:
    concept: Concept
    p: np.ndarray  # flat SI parameter vector
    q: np.ndarray  # moving joint values
    pose: np.ndarray  # world <- concept
    # Per-grasp (lo, hi, default) of the free parameters: fixed once the parameters are.
    _ranges: dict[str, tuple[np.ndarray, ...]] = field(
        default_factory=dict, compare=False, repr=False
    )

    @staticmethod
    def create(
        concept: Concept, pose: Any, joints: Mapping[str, float], params: Mapping[str, Any]
    ) -> Instance:
        p = concept._packer.pack(params, concept.name)  # concept.pack without re-packing kwargs
        held, low, high = concept.function("instance_checks")(p)  # requires and joint ranges
        holds = held.ravel().tolist()
        if holds.count(1.0) != len(holds):  # NaN counts as false, like every value but 1
            check_requirements(holds, concept.entry["requires"], concept.params, p, concept.name)
        q = np.zeros(len(concept.moving_joints))
        if joints:
            if not isinstance(joints, Mapping):
                raise ParameterError(
                    f"joints must be a mapping {{name: value}}, not {type(joints).__name__}"
                )
            lo, hi = low.ravel().tolist(), high.ravel().tolist()
            for name, value in joints.items():
                if name not in concept.moving_joints:
                    raise UnknownNameError(
                        f"{concept.name} has no moving joint {name!r}"
                        + suggest(name, concept.moving_joints)
                        if concept.moving_joints
                        else f"{concept.name} has no moving joints (asked for {name!r})"
                    )
                i = concept.moving_joints.index(name)
                value = _joint_number(name, value)
                if not math.isfinite(value) or not lo[i] - 1e-12 <= value <= hi[i] + 1e-12:
                    raise ParameterError(
                        f"joint {name} = {value!r} is outside its range [{lo[i]:g}, {hi[i]:g}]"
                    )
                q[i] = float(value)
        return Instance(concept, p, q, _pose(pose))

    # -- parameters and structure
    @property
    def params(self) -> dict[str, Any]:
        return {s.name: s.decode(self.p[s.offset : s.offset + s.size]) for s in self.concept.params}

    def joint_limits(self) -> dict[str, tuple[float, float]]:
        lo, hi = (
            np.atleast_1d(x).reshape(-1) for x in self.concept.function("joint_limits")(self.p)
        )
        return {n: (float(a), float(b)) for n, a, b in zip(self.concept.moving_joints, lo, hi)}

    def link_pose(self, link: str) -> np.ndarray:
        if link not in self.concept.links:
            raise UnknownNameError(
                f"{self.concept.name} has no link {link!r}" + suggest(link, self.concept.links)
            )
        return self.pose @ self.concept.function("link", link)(self.p, self.q)

    # -- geometry
    def mesh(self, resolution: int = 64) -> Any:
        """A ``trimesh.Trimesh`` of the whole instance in the world, at its joint values."""
        from grace_dsl.runtime.shapes import instance_mesh

        return instance_mesh(self, None, resolution)

    def link_mesh(self, link: str, resolution: int = 64) -> Any:
        """The mesh of one link's shapes, in the world."""
        from grace_dsl.runtime.shapes import instance_mesh

        self.link_pose(link)  # validates the name
        return instance_mesh(self, link, resolution)

    def sdf(self, points: Any) -> np.ndarray:
        """(N,) signed distances of world points to the instance, negative inside."""
        from grace_dsl.runtime.shapes import instance_sdf

        return instance_sdf(self, _points(points))

    def sample_surface(self, n: int, seed: int = 0) -> np.ndarray:
        """(n, 3) world points spread by area over the outer surface (deterministic by seed)."""
        return self.sample_surface_with_normals(n, seed)[0]

    def sample_surface_with_normals(self, n: int, seed: int = 0) -> tuple[np.ndarray, np.ndarray]:
        from grace_dsl.runtime.shapes import instance_samples

        return instance_samples(self, _count("n", n, 0), _count("seed", seed, 0))

    # -- grasps
    def _grasp_entry(self, name: str) -> dict[str, Any]:
        if name not in self.concept.grasps:
            raise UnknownNameError(
                f"{self.concept.name} has no grasp {name!r}" + suggest(name, self.concept.grasps)
            )
        return self.concept.grasps[name]

    def grasp_range(self, name: str) -> dict[str, tuple[float, float]]:
        entry = self._grasp_entry(name)
        lo, hi, _ = self._free_box(name)
        return {f["name"]: (float(a), float(b)) for f, a, b in zip(entry["free"], lo, hi)}

    def _free_box(self, name: str) -> tuple[np.ndarray, ...]:
        if name not in self._ranges:
            outputs = self.concept.function("grasp_range", name)(self.p)
            self._ranges[name] = tuple([x.reshape(-1) for x in outputs])
        return self._ranges[name]

    def _free_vector(self, name: str, free: Mapping[str, float]) -> np.ndarray:
        entry = self._grasp_entry(name)
        names = [f["name"] for f in entry["free"]]
        for k in free:
            if k not in names:
                raise UnknownNameError(
                    f"grasp {name} has no free parameter {k!r}" + suggest(k, names or ["(none)"])
                )
        lo, hi, default = self._free_box(name)
        g = default.copy()
        for i, k in enumerate(names):
            if k in free:
                v = float(free[k])
                if not np.isfinite(v) or not lo[i] - 1e-12 <= v <= hi[i] + 1e-12:
                    raise ParameterError(
                        f"{k} = {v!r} is outside the range of grasp {name}: [{lo[i]:g}, {hi[i]:g}]"
                    )
                g[i] = v
        return g

    def grasp(self, name: str, reference: Any = None, **free: float) -> np.ndarray:
        """The world pose of the gripper for grasp family ``name`` at free parameters ``free``.

        A grasp declared ``symmetric`` is spun about its symmetry axis to the orientation closest
        to ``reference`` (a world rotation or pose, default the Panda's home hand orientation):
        the paper's minimal-rotation rule, which makes the orientation unique.
        """
        g = self._free_vector(name, free)
        pose = self.pose @ self.concept.function("grasp", name)(self.p, self.q, g)
        if self.concept.grasps[name].get("symmetric"):
            axis = np.asarray(self.concept.function("grasp_axis", name)(self.p, g)).reshape(3)
            pose = spin_to_reference(pose, axis, reference)
        return pose

    def grasps(self, name: str, n: int = 16, reference: Any = None) -> np.ndarray:
        """``n`` poses spread evenly over the free-parameter box (deterministic), (n, 4, 4);
        symmetric grasps are spun to ``reference`` as in :meth:`grasp`."""
        if type(n) is not int or n < 1:
            n = _count("n", n, 1)
        entry = self._grasp_entry(name)
        unit = _unit_points(n, len(entry["free"]))  # the spread over the unit box
        fn = self.concept.function("grasps_world", name)  # M G(lo + unit (hi - lo)), one call
        poses = np.ascontiguousarray(fn.batch(self.p, self.q, unit, self.pose[:3]))
        if entry.get("symmetric"):
            lo, hi, _ = self._free_box(name)
            samples = _spread_box(lo, hi, n)
            axes = self.concept.function("grasp_axis", name).batch(self.p, samples)
            poses = spin_to_reference(poses, np.asarray(axes).reshape(-1, 3), reference)
        return poses

    def grasp_width(self, name: str) -> float | None:
        if not self._grasp_entry(name)["has_width"]:
            return None
        return float(np.asarray(self.concept.function("grasp_width", name)(self.p)).reshape(-1)[0])

    # -- actions
    def _action(self, name: str) -> dict[str, Any]:
        if name not in self.concept.actions:
            raise UnknownNameError(
                f"{self.concept.name} has no action {name!r}" + suggest(name, self.concept.actions)
            )
        return self.concept.actions[name]

    def force(self, action: str, grasp: Any) -> np.ndarray:
        """Unit world direction in which the gripper at pose ``grasp`` must push or pull."""
        entry = self._action(action)
        if entry["joint"] is None and entry["verb"] in TWIST_VERBS:
            raise ParameterError(
                f"{action} turns the hand about a fixed axis and has no linear force: "
                f"use inst.twist({action!r})"
            )
        point = _pose(grasp)[:3, 3]  # R f(R^T (t - t_M)) in one native call
        out = self.concept.function("force", action)(self.p, self.q, self.pose[:3], point)
        f = cast(np.ndarray, out).reshape(3)  # one output: an array
        if not math.isfinite(f[0] + f[1] + f[2]):
            raise ParameterError(
                f"the grasp point lies on the axis of {action}'s joint: no linear force moves "
                f"it; turn the hand instead (inst.twist({action!r})) or grasp off the axis"
            )
        return f

    def twist(self, action: str) -> np.ndarray:
        """The unit world axis about which the hand turns to perform ``action`` (right-handed):
        for turning a knob or a cap with a grasp on its axis, where no linear force moves it, and
        for a ``turn``/``rotate`` action with an explicit direction, which is its axis."""
        entry = self._action(action)
        joint = entry["joint"]
        if joint is None and entry["verb"] in TWIST_VERBS:  # the direction, in the world
            axis = self.concept.function("force", action)(self.p, self.q, self.pose[:3], _ORIGIN)
            return np.asarray(axis, dtype=float).reshape(3)
        if joint is None or self.concept.joints[joint]["kind"] == "prismatic":
            raise ParameterError(
                f"action {action} turns nothing: it needs a revolute or continuous joint, "
                "or the verb turn or rotate with a direction"
            )
        i = self.concept.moving_joints.index(joint)
        axes, _ = self.concept.function("joint_axes")(self.p, self.q)
        axis = np.asarray(axes).reshape(-1, 3)[i]  # the opening sense is already in the axis
        sign = 1.0 if entry["sense"] == "opening" else -1.0
        return sign * (self.pose[:3, :3] @ axis)

    def rank(
        self, action: str, gripper: Any = None, samples: int = 32, reference: Any = None
    ) -> tuple[Any, ...]:
        """The manipulation functions of ``action`` judged for ``gripper`` (default the Panda),
        best first: see :func:`grace_dsl.runtime.manipulation.rank`."""
        from grace_dsl.runtime.gripper import Gripper
        from grace_dsl.runtime.manipulation import rank

        return rank(self, action, gripper or Gripper.panda(), samples, reference)

    def follow(self, action: str, grasp: Any, to: float, steps: int = 32) -> np.ndarray:
        """The gripper path (steps, 4, 4) as the action's joint moves from its value to ``to``."""
        entry = self._action(action)
        joint = entry["joint"]
        if joint is None:
            raise ParameterError(f"action {action} moves no joint; it has a fixed direction")
        steps = _count("steps", steps, 2)
        i = self.concept.moving_joints.index(joint)
        lo, hi = self.joint_limits()[joint]
        to = _joint_number(joint, to)
        if not lo - 1e-12 <= to <= hi + 1e-12:
            raise ParameterError(f"{joint} cannot reach {to!r}: its range is [{lo:g}, {hi:g}]")
        sense = 1.0 if entry["sense"] == "opening" else -1.0
        if sense * (to - self.q[i]) < 0:
            raise ParameterError(
                f"{action} moves {joint} {'up' if sense > 0 else 'down'} from {self.q[i]:g}, "
                f"so it cannot end at {to:g}; use the action of the other sense"
            )
        child = self.concept.joints[joint]["child"]
        link = self.concept.function("link", child)
        start = self.pose @ link(self.p, self.q)
        attached = np.linalg.solve(start, _pose(grasp))
        path = []
        for value in np.linspace(self.q[i], to, steps):
            q = self.q.copy()
            q[i] = value
            path.append(self.pose @ link(self.p, q) @ attached)
        return np.asarray(path)


def _spread(ranges: list[tuple[float, float]], n: int) -> np.ndarray:
    """Deterministic points over a box: a grid along one axis, a Halton sequence in more."""
    lows = np.array([r[0] for r in ranges], dtype=float)
    highs = np.array([r[1] for r in ranges], dtype=float)
    return _spread_box(lows, highs, n)


def _spread_box(lows: np.ndarray, highs: np.ndarray, n: int) -> np.ndarray:
    """``_spread`` over the box [lows, highs] given as arrays, (n, d)."""
    d = lows.size
    if d == 0:
        return np.zeros((n, 0))
    if d == 1:  # Python floats: a third of the cost of size-1 array arithmetic
        lo = float(lows[0])
        return _unit_points(n, 1) * (float(highs[0]) - lo) + lo
    return lows + _unit_points(n, d) * (highs - lows)


@lru_cache(maxsize=128)
def _unit_points(n: int, d: int) -> np.ndarray:
    """The spread over the unit box, computed once per (n, d) (read-only)."""
    if d == 1:
        pts = np.linspace(0.0, 1.0, n).reshape(n, 1)
    else:
        primes = [2, 3, 5, 7, 11, 13, 17, 19]
        pts = np.array([[_halton(i + 1, primes[k]) for k in range(d)] for i in range(n)])
    pts.flags.writeable = False
    return pts


def _halton(i: int, base: int) -> float:
    f, r = 1.0, 0.0
    while i > 0:
        f /= base
        r += f * (i % base)
        i //= base
    return r

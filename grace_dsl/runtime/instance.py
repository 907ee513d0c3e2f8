"""An instantiated concept: grasp poses, force directions and joint motion in world coordinates.

World quantities follow the paper: ``G_world = M G_local`` and ``F_world = R F_local``, where M is
the instance pose and R its rotation.

An ``Instance`` is an immutable value: its arrays are read-only copies, equal instances compare
and hash equal, and ``with_joints``/``with_pose`` derive new instances without re-checking the
parameters (which only ``instantiate`` validates). Every quantity it returns is finite, or a
typed error names the formula (``EvaluationError``) or the bad input (``ParameterError``).
"""

from __future__ import annotations

import math
from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field
from typing import TYPE_CHECKING, Any, cast

import numpy as np

from grace_dsl.compiler.types import format_si
from grace_dsl.runtime import masks
from grace_dsl.runtime.concept import (
    check_domain,
    check_ranges_mode,
    check_requirements,
    suggest,
)
from grace_dsl.runtime.errors import (
    EvaluationError,
    GraceError,
    GraspConditionError,
    ParameterError,
    UnknownNameError,
)
from grace_dsl.runtime.gripper import Gripper
from grace_dsl.runtime.inputs import (
    MAX_GRASPS,
    MAX_RANK_SAMPLES,
    MAX_RESOLUTION,
    MAX_SAMPLES,
    MAX_STEPS,
    as_count,
    as_number,
    as_points,
    as_pose,
    as_rotation,
    check_pose,
    merge_names,
    rigid_problem,
)
from grace_dsl.runtime.manipulation import Option, rank
from grace_dsl.runtime.sampling import spread, spread_box, unit_points
from grace_dsl.runtime.specs import TWIST_VERBS, ActionSpec, GraspSpec
from grace_dsl.runtime.symmetry import spin_to_reference
from grace_dsl.tolerances import RANGE_SLACK

if TYPE_CHECKING:
    from grace_dsl.runtime.library import Concept

# Kept importable from here for existing callers (verify, export, tests).
__all__ = ["TWIST_VERBS", "Instance", "rigid_problem"]
_spread = spread
_pose = as_pose

_ORIGIN = np.zeros(3)  # any point: an explicit direction is the same everywhere
_TOL = RANGE_SLACK  # slack on range bounds
_AXIS = 1e-5  # metres: within this of a joint's axis the compiled force is NaN (1e-6) on purpose
_Limits = tuple[tuple[float, ...], tuple[float, ...]]


def _read_only(a: np.ndarray) -> np.ndarray:
    a.setflags(write=False)  # half the cost of a.flags.writeable = False
    return a


def _finite(a: np.ndarray) -> bool:
    """All entries finite: one float sum for the common case, the exact test when it is not."""
    return math.isfinite(float(a.sum())) or bool(np.isfinite(a).all())


@dataclass(frozen=True, eq=False)
class Instance:
    """A concept with parameter values ``p`` (flat, SI), joint values ``q`` and a world pose."""

    concept: Concept
    p: np.ndarray  # flat SI parameter vector (read-only)
    q: np.ndarray  # moving joint values (read-only)
    pose: np.ndarray  # world <- concept (read-only)
    # joint ranges at p (lo, hi): fixed once the parameters are
    _limits: _Limits = field(repr=False)
    # per-grasp (lo, hi, default) of the free parameters, filled on first use, shared by the
    # instances with_joints/with_pose derive (they have the same parameters)
    _ranges: dict[str, tuple[np.ndarray, ...]] = field(default_factory=dict, repr=False)

    @staticmethod
    def create(
        concept: Concept,
        pose: Any,
        joints: Any,
        params: Mapping[str, Any],
        ranges: str = "typical",
    ) -> Instance:
        """Validate parameters, requirements, joint values and pose (``Concept.instantiate``).

        ``ranges="typical"`` checks each parameter against its declared range. ``"valid"``
        checks its domain instead (``check_domain``) and then the instance itself: every joint
        range and every grasp's free-parameter range non-empty, every shape well-formed
        (``ShapeTree.check``), since only the typical ranges are verified ahead of time."""
        valid = ranges != "typical" and check_ranges_mode(ranges) == "valid"
        if valid:
            p = concept._valid_packer.pack(params, concept.name)
            check_domain(concept.params, p, concept.name)
        else:
            p = concept._packer.pack(params, concept.name)  # concept.pack without re-packing
        held, low, high = concept.function("instance_checks")(p)  # requires and joint ranges
        holds = held.ravel().tolist()
        if holds.count(1.0) != len(holds):  # NaN counts as false, like every value but 1
            check_requirements(holds, concept.entry["requires"], concept.params, p, concept.name)
        limits = (tuple(low.ravel().tolist()), tuple(high.ravel().tolist()))
        _check_limits(concept, limits)
        q = np.zeros(len(concept.moving_joints))
        if joints is not None:
            _set_joints(concept, q, _present_joints(concept, p, joints), limits)
        inst = Instance(concept, _read_only(p), _read_only(q), _read_only(as_pose(pose)), limits)
        if valid:
            _check_valid(inst)
        return inst

    def with_joints(self, joints: Mapping[str, Any] | None = None, /, **values: Any) -> Instance:
        """The same instance with some joints moved (the others keep their values): only the
        joint values are checked, against ranges computed when the instance was made."""
        q = self.q.copy()
        given = _present_joints(self.concept, self.p, merge_names("joints", joints, values))
        _set_joints(self.concept, q, given, self._limits)
        return Instance(self.concept, self.p, _read_only(q), self.pose, self._limits, self._ranges)

    def with_pose(self, pose: Any, /) -> Instance:
        """The same instance at another world pose (4x4, rigid; copied)."""
        return Instance(
            self.concept, self.p, self.q, _read_only(as_pose(pose)), self._limits, self._ranges
        )

    # -- value semantics
    def __eq__(self, other: object) -> bool:
        if not isinstance(other, Instance):
            return NotImplemented
        return (
            _same_concept(self.concept, other.concept)
            and np.array_equal(self.p, other.p)
            and np.array_equal(self.q, other.q)
            and np.array_equal(self.pose, other.pose)
        )

    def __hash__(self) -> int:
        cached = self.__dict__.get("_hash")
        if cached is None:  # + 0.0 makes -0.0 and 0.0, which compare equal, hash equal
            arrays = (self.p, self.q, self.pose)
            cached = hash((self.concept.name, *((a + 0.0).tobytes() for a in arrays)))
            object.__setattr__(self, "_hash", cached)
        return cached

    # -- parameters and structure
    @property
    def params(self) -> dict[str, Any]:
        return {s.name: s.decode(self.p[s.offset : s.offset + s.size]) for s in self.concept.params}

    @property
    def joints(self) -> dict[str, float]:
        """``{joint: value}`` of the moving joints this instance has: a copy its counts leave
        out (``slide[3]`` at ``n = 2``) or an option it did not choose is not listed, though
        ``q`` (the compiled functions' input) keeps a value for every compiled joint."""
        values = self.q.tolist()
        return {n: values[i] for i, n in self._present_joints()}

    def joint_limits(self) -> dict[str, tuple[float, float]]:
        """``{joint: (lo, hi)}`` at these parameters, for the joints it has (as ``joints``); a
        continuous joint's are (-inf, inf)."""
        lo, hi = self._limits
        return {n: (lo[i], hi[i]) for i, n in self._present_joints()}

    def _present_joints(self) -> list[tuple[int, str]]:
        """(index in ``q``, name) of the moving joints this instance has."""
        names = self.concept.moving_joints
        if not masks.has_masks(self.concept.entry):
            return list(enumerate(names))
        here = masks.presence(self.concept.entry, self._mask_params())
        return [(i, n) for i, n in enumerate(names) if here(n)]

    @property
    def grasp_names(self) -> tuple[str, ...]:
        """The grasps this instance has (compiled names; the chosen variant option's only)."""
        return self._members(self.concept.grasps)

    @property
    def action_names(self) -> tuple[str, ...]:
        """The actions this instance has (compiled names), as ``grasp_names``."""
        return self._members(self.concept.actions)

    def _members(self, names: Any) -> tuple[str, ...]:
        if not masks.has_masks(self.concept.entry):
            return tuple(names)
        here = masks.presence(self.concept.entry, self._mask_params())
        return tuple(n for n in names if here(n))

    @property
    def links(self) -> tuple[str, ...]:
        """The links this instance has: the concept's, less copies its counts leave out."""
        names = tuple(self.concept.links)
        entry = self.concept.entry
        if not masks.has_masks(entry):
            return names
        params = self._mask_params()
        return tuple(n for n in names if masks.present(entry, params, n))

    def count(self, name: str) -> int:
        """How many copies of a repeated member (``drawer`` of ``for i in 0..n``) it has."""
        return masks.count(self.concept.entry, self._mask_params(), name)

    def indices(self, name: str) -> list[str]:
        """The indices of the copies of a repeated member it has: ``["[0]", "[1]"]``."""
        return masks.indices(self.concept.entry, self._mask_params(), name)

    def _present(self, name: Any, kind: str) -> Any:
        """The compiled name ``name`` means here (variants read through their chosen option);
        ``UnknownNameError`` for a copy this instance does not have (``runtime/masks.py``)."""
        if isinstance(name, str) and masks.has_masks(self.concept.entry):
            return masks.canonical(self.concept.entry, self._mask_params(), name, kind)
        return name

    def _mask_params(self) -> dict[str, Any]:
        """``params``, decoded once per instance (it is immutable) for the name checks."""
        cached = self.__dict__.get("_params")
        if cached is None:
            cached = self.params
            object.__setattr__(self, "_params", cached)
        return cached

    def link_pose(self, link: str) -> np.ndarray:
        link = self._present(link, "link")
        if not isinstance(link, str) or link not in self.concept.links:
            raise UnknownNameError(
                f"{self.concept.name} has no link {link!r}" + suggest(link, self.concept.links)
            )
        pose = self.pose @ self.concept.function("link", link)(self.p, self.q)
        if not _finite(pose):
            raise self._evaluation(f"the pose of link {link}", self._link_where(link))
        return pose

    # -- geometry
    def mesh(self, resolution: int = 64) -> Any:
        """A ``trimesh.Trimesh`` of the whole instance in the world, at its joint values."""
        from grace_dsl.runtime.shapes import instance_mesh

        resolution = as_count("resolution", resolution, 3, MAX_RESOLUTION)
        self._check_links()
        return self._finite_mesh(_geometry(lambda: instance_mesh(self, None, resolution)))

    def link_mesh(self, link: str, resolution: int = 64) -> Any:
        """The mesh of one link's shapes, in the world."""
        from grace_dsl.runtime.shapes import instance_mesh

        self.link_pose(link)  # validates the name
        resolution = as_count("resolution", resolution, 3, MAX_RESOLUTION)
        self._check_links()
        return self._finite_mesh(_geometry(lambda: instance_mesh(self, link, resolution)))

    def _check_links(self) -> None:
        """Every link pose finite (once per instance): the geometry moves shapes by them, and an
        infinite motion would surface there as a misleading complaint about the points."""
        if "_links_ok" not in self.__dict__:
            for link in self.links:
                self.link_pose(link)
            object.__setattr__(self, "_links_ok", True)

    def _finite_mesh(self, mesh: Any) -> Any:
        if len(mesh.vertices) and not _finite(np.asarray(mesh.vertices)):
            raise self._evaluation("a mesh vertex", self._shapes_where())
        return mesh

    def sdf(self, points: Any) -> np.ndarray:
        """(N,) signed distances of world points to the instance, negative inside."""
        from grace_dsl.runtime.shapes import instance_sdf

        pts = as_points(points)
        self._check_links()
        d = np.asarray(_geometry(lambda: instance_sdf(self, pts)))
        if not _finite(d):
            raise self._evaluation("a signed distance", self._shapes_where())
        return d

    def sample_surface(self, n: int, seed: int = 0) -> np.ndarray:
        """(n, 3) world points spread by area over the outer surface (deterministic by seed)."""
        return self.sample_surface_with_normals(n, seed)[0]

    def sample_surface_with_normals(self, n: int, seed: int = 0) -> tuple[np.ndarray, np.ndarray]:
        from grace_dsl.runtime.shapes import instance_samples

        n = as_count("n", n, 0, MAX_SAMPLES)
        seed = as_count("seed", seed, 0, 2**64 - 1)
        self._check_links()
        points, normals = _geometry(lambda: instance_samples(self, n, seed))
        if not (_finite(points) and _finite(normals)):
            raise self._evaluation("a surface sample", self._shapes_where())
        return points, normals

    # -- grasps
    def _grasp_spec(self, name: Any) -> GraspSpec:
        name = self._present(name, "grasp")
        spec = self.concept.grasps.get(name) if isinstance(name, str) else None
        if spec is None:
            raise UnknownNameError(
                f"{self.concept.name} has no grasp {name!r}" + suggest(name, self.concept.grasps)
            )
        return spec

    def grasp_range(self, name: str) -> dict[str, tuple[float, float]]:
        spec = self._grasp_spec(name)
        lo, hi, _ = self._free_box(spec)
        return {f: (float(a), float(b)) for f, a, b in zip(spec.free_names, lo, hi)}

    def _free_box(self, spec: GraspSpec) -> tuple[np.ndarray, ...]:
        box = self._ranges.get(spec.name)
        if box is None:
            outputs = self.concept.function("grasp_range", spec.name)(self.p)
            box = tuple([_read_only(x.reshape(-1)) for x in outputs])
            lo, hi, default = (x.tolist() for x in box)
            # NaN fails every comparison: this refuses NaN and infinite ranges and defaults
            if not all(
                -math.inf < a <= b < math.inf and math.isfinite(c)
                for a, b, c in zip(lo, hi, default)
            ):
                raise self._evaluation(
                    f"the range of grasp {spec.name}'s free parameters "
                    f"({_pairs(spec.free_names, lo, hi, default)})",
                    spec.where,
                )
            self._ranges[spec.name] = box
        return box

    def _free_vector(self, spec: GraspSpec, free: Mapping[str, Any]) -> np.ndarray:
        names = spec.free_names
        for k in free:
            if k not in names:
                raise UnknownNameError(
                    f"grasp {spec.name} has no free parameter {k!r}"
                    + suggest(k, names or ["(none)"])
                )
        lo, hi, default = self._free_box(spec)
        if not free:
            return default
        g = default.copy()
        for i, k in enumerate(names):
            if k in free:
                v = as_number(k, free[k])
                if not lo[i] - _TOL <= v <= hi[i] + _TOL:  # NaN fails too
                    raise ParameterError(
                        f"{k} = {v!r} is outside the range of grasp {spec.name}: "
                        f"[{lo[i]:g}, {hi[i]:g}]"
                    )
                g[i] = v
        return g

    def grasp(
        self,
        name: str,
        /,
        reference: Any = None,
        free: Mapping[str, Any] | None = None,
        **values: Any,
    ) -> np.ndarray:
        """The world pose of the gripper for grasp family ``name`` at free parameters (keywords,
        or the mapping ``free``, which also carries names such as ``reference``).

        A grasp declared ``symmetric`` is spun about its symmetry axis to the orientation closest
        to ``reference`` (a world rotation or pose, default the Panda's home hand orientation):
        the paper's minimal-rotation rule, which makes the orientation unique.
        """
        spec = self._grasp_spec(name)
        ref = None if reference is None else as_rotation(reference)
        g = self._free_vector(spec, merge_names("free", free, values))
        why = self.grasp_inapplicable(spec.name)
        if why is not None:
            raise GraspConditionError(why)
        pose = self.pose @ self.concept.function("grasp", spec.name)(self.p, self.q, g)
        if spec.symmetric:
            axis = np.asarray(self.concept.function("grasp_axis", spec.name)(self.p, g)).reshape(3)
            pose = spin_to_reference(pose, axis, ref)
        if not _finite(pose):
            raise self._evaluation(f"the pose of grasp {spec.name}", spec.where)
        return pose

    def grasp_applies(self, name: str) -> bool:
        """Whether grasp family ``name`` applies at these parameters and joint values: its
        ``when`` condition holds (a family without one always applies)."""
        return self.grasp_inapplicable(name) is None

    def grasp_inapplicable(self, name: str) -> str | None:
        """Why grasp family ``name`` does not apply here (its ``when`` condition, where it is
        written and the joint values it reads), or None when it applies."""
        spec = self._grasp_spec(name)
        if spec.when is None:
            return None
        _, holds = self.concept.function("grasp_when", spec.name)(self.p, self.q)
        if float(np.asarray(holds).reshape(-1)[0]) > 0.5:
            return None
        joints = self.joints
        values = ", ".join(
            f"{j} = {format_si(joints[j], _dim(self.concept, j))}"
            for j in spec.when_joints
            if j in joints
        )
        at = f" ({spec.when_where})" if spec.when_where else ""
        here = f"; here {values}" if values else " at these parameters"
        return f"grasp {spec.name} applies only when {spec.when}{at}{here}"

    def grasps(self, name: str, /, n: int = 16, reference: Any = None) -> np.ndarray:
        """``n`` poses spread evenly over the free-parameter box (deterministic), (n, 4, 4);
        symmetric grasps are spun to ``reference`` as in :meth:`grasp`. They are the family's
        geometry whether or not its ``when`` condition holds (:meth:`grasp_applies` says)."""
        if type(n) is not int or not 1 <= n <= MAX_GRASPS:
            n = as_count("n", n, 1, MAX_GRASPS)
        spec = self._grasp_spec(name)
        ref = None if reference is None else as_rotation(reference)
        unit = unit_points(n, len(spec.free))  # the spread over the unit box
        fn = self.concept.function("grasps_world", spec.name)  # M G(lo + unit (hi - lo)), 1 call
        poses = np.ascontiguousarray(fn.batch(self.p, self.q, unit, self.pose[:3]))
        if spec.symmetric:
            lo, hi, _ = self._free_box(spec)
            samples = spread_box(lo, hi, n)
            axes = self.concept.function("grasp_axis", spec.name).batch(self.p, samples)
            poses = spin_to_reference(poses, np.asarray(axes).reshape(-1, 3), ref)
        if not _finite(poses):
            self._free_box(spec)  # a NaN range is the likelier cause: name it
            raise self._evaluation(f"a pose of grasp {spec.name}", spec.where)
        return poses

    def grasp_width(self, name: str) -> float | None:
        spec = self._grasp_spec(name)
        if not spec.has_width:
            return None
        fn = self.concept.function("grasp_width", spec.name)
        width = float(np.asarray(fn(self.p)).reshape(-1)[0])
        if not math.isfinite(width):
            raise self._evaluation(f"the width of grasp {spec.name}", spec.where)
        return width

    # -- actions
    def _action_spec(self, name: Any) -> ActionSpec:
        name = self._present(name, "action")
        spec = self.concept.actions.get(name) if isinstance(name, str) else None
        if spec is None:
            raise UnknownNameError(
                f"{self.concept.name} has no action {name!r}" + suggest(name, self.concept.actions)
            )
        return spec

    def _action(self, name: str) -> ActionSpec:  # the old name, kept for callers
        return self._action_spec(name)

    def force(self, action: str, /, grasp: Any) -> np.ndarray:
        """Unit world direction in which the gripper at pose ``grasp`` must push or pull."""
        spec = self._action_spec(action)
        if spec.fixed_twist:
            raise ParameterError(
                f"{action} turns the hand about a fixed axis and has no linear force: "
                f"use inst.twist({action!r})"
            )
        point = _grasp_point(grasp)  # R f(R^T (t - t_M)) in one native call
        out = self.concept.function("force", spec.name)(self.p, self.q, self.pose[:3], point)
        f = cast(np.ndarray, out).reshape(3)  # one output: an array
        if not math.isfinite(f[0] + f[1] + f[2]):
            self._force_failure(spec, point)
        return f

    def _force_failure(self, spec: ActionSpec, point: np.ndarray) -> None:
        """Raise the error for a non-finite force: the grasp point on the joint's axis (a
        ``ParameterError``: turn instead), or a formula that is not finite here."""
        if spec.joint is not None and self.concept.joints[spec.joint].turns:
            i = self.concept.joint_index[spec.joint]
            axes, origins = self.concept.function("joint_axes")(self.p, self.q)
            a = np.asarray(axes, float).reshape(-1, 3)[i]
            o = np.asarray(origins, float).reshape(-1, 3)[i]
            local = self.pose[:3, :3].T @ (point - self.pose[:3, 3])
            with np.errstate(all="ignore"):  # inf or NaN here is the answer, not a warning
                off = float(np.linalg.norm(np.cross(a, local - o)))
            if math.isfinite(off) and off <= _AXIS * max(1.0, float(np.linalg.norm(a))):
                raise ParameterError(
                    f"the grasp point lies on the axis of {spec.name}'s joint: no linear force "
                    f"moves it; turn the hand instead (inst.twist({spec.name!r})) or grasp off "
                    "the axis"
                )
        raise self._evaluation(f"the force of {spec.name}", spec.where)

    def twist(self, action: str) -> np.ndarray:
        """The unit world axis about which the hand turns to perform ``action`` (right-handed):
        for turning a knob or a cap with a grasp on its axis, where no linear force moves it, and
        for a ``turn``/``rotate`` action with an explicit direction, which is its axis."""
        spec = self._action_spec(action)
        if spec.fixed_twist:  # the direction, in the world
            fn = self.concept.function("force", spec.name)
            axis = np.asarray(fn(self.p, self.q, self.pose[:3], _ORIGIN), dtype=float).reshape(3)
        else:
            if spec.joint is None or not self.concept.joints[spec.joint].turns:
                raise ParameterError(
                    f"action {action} turns nothing: it needs a revolute or continuous joint, "
                    "or the verb turn or rotate with a direction"
                )
            axes, _ = self.concept.function("joint_axes")(self.p, self.q)
            # the opening sense is already in the axis
            local = np.asarray(axes).reshape(-1, 3)[self.concept.joint_index[spec.joint]]
            axis = spec.sign * (self.pose[:3, :3] @ local)
        if not _finite(axis):
            raise self._evaluation(f"the twist axis of {spec.name}", spec.where)
        return axis

    def rank(
        self,
        action: str,
        /,
        gripper: Gripper | None = None,
        samples: int = 32,
        reference: Any = None,
        to: float | None = None,
        also: Sequence[str] = (),
    ) -> tuple[Option, ...]:
        """The manipulation functions of ``action`` judged for ``gripper`` (default the Panda),
        best first: see :func:`grace_dsl.runtime.manipulation.rank`. ``to``: judge the follow
        path only as far as this joint value (default the end of the range the action drives
        toward): a hand that carries a lid part of the way, then takes it again otherwise.
        ``also``: grasps (names) judged besides those the action names."""
        if to is not None:
            to = as_number("to", to)
            if not math.isfinite(to):
                raise ParameterError(f"rank's to must be a finite joint value, not {to!r}")
        if gripper is None:
            gripper = Gripper.panda()
        elif not isinstance(gripper, Gripper):
            raise ParameterError(
                f"gripper must be a grace_dsl.Gripper (e.g. Gripper.panda()), not {gripper!r:.60}"
            )
        samples = as_count("samples", samples, 1, MAX_RANK_SAMPLES)
        ref = None if reference is None else as_rotation(reference)
        if isinstance(also, str) or not all(isinstance(g, str) for g in also):
            raise ParameterError(f"rank's also is a list of grasp names, not {also!r:.60}")
        return rank(self, action, gripper, samples, ref, to, tuple(also))

    def follow(
        self,
        action: str,
        /,
        grasp: Any,
        to: float | None = None,
        steps: int = 32,
        *,
        distance: float | None = None,
        beyond_range: bool = False,
    ) -> np.ndarray:
        """The gripper path (steps, 4, 4) of ``action`` from the pose ``grasp``.

        Along a joint: the joint moves from its value to ``to``, which must lie in the joint's
        range unless ``beyond_range=True`` (the real object's stop may lie past the concept's).
        Toward a fixed direction (no joint): the hand travels ``distance`` (metres) along the
        action's force; for ``turn``/``rotate`` with a direction, it turns ``distance`` radians
        about that axis through the grasp's origin.
        """
        spec = self._action_spec(action)
        if not isinstance(beyond_range, (bool, np.bool_)):
            raise ParameterError(f"beyond_range is True or False, not {beyond_range!r:.60}")
        steps = as_count("steps", steps, 2, MAX_STEPS)
        if spec.joint is None:
            if to is not None:
                raise ParameterError(
                    f"action {action} moves no joint, so it has no joint value to go to: give "
                    f"how far the hand travels, inst.follow({action!r}, grasp=..., distance=d)"
                )
            if distance is None:
                raise ParameterError(
                    f"action {action} moves no joint: give how far the hand travels, "
                    f"inst.follow({action!r}, grasp=..., distance=d)"
                )
            return self._follow_direction(spec, _grasp_pose(grasp), distance, steps)
        if distance is not None:
            raise ParameterError(
                f"action {action} moves joint {spec.joint}: give the joint value to reach, "
                f"inst.follow({action!r}, grasp=..., to=q), not a distance"
            )
        if to is None:
            raise ParameterError(
                f"action {action} moves joint {spec.joint}: give the joint value to reach, "
                f"inst.follow({action!r}, grasp=..., to=q)"
            )
        return self._follow_joint(spec, _grasp_pose(grasp), to, steps, bool(beyond_range))

    def _follow_joint(
        self, spec: ActionSpec, held: np.ndarray, to: Any, steps: int, beyond: bool
    ) -> np.ndarray:
        joint = spec.joint
        assert joint is not None
        i = self.concept.joint_index[joint]
        lo, hi = self._limits[0][i], self._limits[1][i]
        to = as_number(f"joint {joint}", to)
        if not math.isfinite(to):
            raise ParameterError(f"{joint} cannot reach {to!r}: a joint value is finite")
        if not beyond and not lo - _TOL <= to <= hi + _TOL:
            raise ParameterError(
                f"{joint} cannot reach {to!r}: its range is [{lo:g}, {hi:g}] (pass "
                "beyond_range=True when the real object's stop lies past the concept's)"
            )
        q0 = float(self.q[i])
        if spec.sign * (to - q0) < 0:
            raise ParameterError(
                f"{spec.name} moves {joint} {'up' if spec.opening else 'down'} from {q0:g}, "
                f"so it cannot end at {to:g}; use the action of the other sense"
            )
        link = self.concept.function("link", self.concept.joints[joint].child)
        start = self.pose @ link(self.p, self.q)
        attached = np.linalg.solve(start, held)
        qs = np.tile(self.q, (steps, 1))
        qs[:, i] = np.linspace(q0, to, steps)
        poses = np.asarray(link.batch(self.p, qs), float).reshape(steps, 4, 4)
        path = np.einsum("ij,njk,kl->nil", self.pose, poses, attached)
        if not _finite(path):
            raise self._evaluation(f"the path of {spec.name}", spec.where)
        return path

    def _follow_direction(
        self, spec: ActionSpec, held: np.ndarray, distance: Any, steps: int
    ) -> np.ndarray:
        """Translate ``held`` along the action's force (or turn it about its fixed axis)."""
        unit = "rad" if spec.fixed_twist else "m"
        d = as_number(f"distance ({unit})", distance)
        if not (math.isfinite(d) and d >= 0):
            raise ParameterError(
                f"distance must be a finite travel >= 0 ({unit}) in the sense of {spec.name}, "
                f"got {distance!r:.60}; the action of the other sense goes back"
            )
        t = np.linspace(0.0, d, steps)
        path = np.tile(held, (steps, 1, 1))
        if spec.fixed_twist:
            axis = self.twist(spec.name)
            path[:, :3, :3] = _rotations(axis, t) @ held[:3, :3]
        else:
            f = self.force(spec.name, grasp=held)
            path[:, :3, 3] = held[:3, 3] + np.outer(t, f)
        if not _finite(path):
            raise self._evaluation(f"the path of {spec.name}", spec.where)
        return path

    # -- errors
    def _evaluation(self, what: str, where: str) -> EvaluationError:
        return EvaluationError(
            f"{self.concept.name}: {what} is not finite at these parameters ({where}); "
            f"parameters {_short(self.params)}, joints {_short(self.joints)}"
        )

    def _link_where(self, link: str) -> str:
        for j in self.concept.joints.values():
            if j.child == link and j.moving:
                return j.where
        return f"{self.concept.entry.get('file', '?')}, link {link} of {self.concept.name}"

    def _shapes_where(self) -> str:
        return f"{self.concept.entry.get('file', '?')}, the shapes of {self.concept.name}"


def _check_limits(concept: Concept, limits: _Limits) -> None:
    """A joint range that is NaN at these parameters would let any value through: refuse it
    (a continuous joint's is (-inf, inf), which is fine)."""
    lo, hi = sum(limits[0]), sum(limits[1])
    if lo == lo and hi == hi:  # no NaN in either (-inf + inf cannot occur within one side)
        return
    for name, a, b in zip(concept.moving_joints, *limits):
        if a != a or b != b:
            raise EvaluationError(
                f"{concept.name}: the range of joint {name} is [{a:g}, {b:g}] at these "
                f"parameters ({concept.joints[name].where}); check its range formula"
            )


def _check_valid(inst: Instance) -> None:
    """The checks ``ranges="valid"`` adds: a ``ParameterError`` naming the joint, grasp or
    shape that the parameters leave empty or malformed."""
    from grace_dsl.runtime.shapes import ShapeTree

    concept = inst.concept
    for name, a, b in zip(concept.moving_joints, *inst._limits):
        if not a <= b:
            raise ParameterError(
                f"{concept.name}: the range of joint {name} is empty at these parameters "
                f"([{a:g}, {b:g}], {concept.joints[name].where})"
            )
    for spec in concept.grasps.values():
        if not spec.free_names:
            continue
        lo, hi, default = (
            np.asarray(x, float).reshape(-1)
            for x in concept.function("grasp_range", spec.name)(inst.p)
        )
        if not (np.all(lo <= hi) and np.all(np.isfinite(default))):
            pairs = _pairs(spec.free_names, lo.tolist(), hi.tolist(), default.tolist())
            raise ParameterError(
                f"{concept.name}: the range of grasp {spec.name}'s free parameters is empty at "
                f"these parameters ({pairs}; {spec.where})"
            )
    ShapeTree(inst).check()  # a ShapeError (a ParameterError) names the shape


def _present_joints(concept: Concept, p: np.ndarray, joints: Any) -> Any:
    """``joints`` with each name read as the instance with parameters ``p`` means it (a joint
    of a variant part through the chosen option); ``UnknownNameError`` naming the valid
    indices for a copy it does not have (``runtime/masks.py``)."""
    entry = concept.entry
    if not masks.has_masks(entry) or not isinstance(joints, Mapping):
        return joints
    params = {s.name: s.decode(p[s.offset : s.offset + s.size]) for s in concept.params}
    return {
        masks.canonical(entry, params, n, "joint") if isinstance(n, str) else n: v
        for n, v in joints.items()
    }


def _set_joints(concept: Concept, q: np.ndarray, joints: Any, limits: _Limits) -> None:
    """Write validated joint values into ``q``."""
    if not isinstance(joints, Mapping):
        raise ParameterError(
            f"joints must be a mapping {{name: value}}, not {type(joints).__name__}"
        )
    index = concept.joint_index
    lo, hi = limits
    for name, value in joints.items():
        i = index.get(name) if isinstance(name, str) else None
        if i is None:
            raise UnknownNameError(
                f"{concept.name} has no moving joint {name!r}"
                + suggest(name, concept.moving_joints)
                if concept.moving_joints
                else f"{concept.name} has no moving joints (asked for {name!r})"
            )
        v = value if type(value) is float else as_number(f"joint {name} (rad or m)", value)
        if not (lo[i] - _TOL <= v <= hi[i] + _TOL and math.isfinite(v)):  # NaN fails too
            raise ParameterError(
                f"joint {name} = {v!r} is outside its range [{lo[i]:g}, {hi[i]:g}]"
            )
        q[i] = v


def _rotations(axis: np.ndarray, angles: np.ndarray) -> np.ndarray:
    """(n, 3, 3) rotations about the unit ``axis`` by each angle (Rodrigues)."""
    k = np.array([[0, -axis[2], axis[1]], [axis[2], 0, -axis[0]], [-axis[1], axis[0], 0]])
    s, c = np.sin(angles)[:, None, None], np.cos(angles)[:, None, None]
    return np.eye(3) + s * k + (1 - c) * (k @ k)


def _grasp_pose(grasp: Any) -> np.ndarray:
    """A gripper pose given to ``force`` or ``follow`` (a rigid 4x4 pose, not copied)."""
    if grasp is None:  # check_pose reads None as "no pose given": the identity
        raise ParameterError("grasp must be the gripper's 4x4 world pose (e.g. inst.grasp(name))")
    return check_pose(grasp, "grasp")


def _grasp_point(grasp: Any) -> np.ndarray:
    """The position of a gripper pose given to ``force``."""
    return _grasp_pose(grasp)[:3, 3]


def _same_concept(a: Concept, b: Concept) -> bool:
    return a is b or (a.name == b.name and a.entry == b.entry)


def _pairs(names: tuple[str, ...], lo: list[float], hi: list[float], default: list[float]) -> str:
    return ", ".join(f"{n} in [{a:g}, {b:g}] = {c:g}" for n, a, b, c in zip(names, lo, hi, default))


def _short(values: Mapping[str, Any], limit: int = 200) -> str:
    text = ", ".join(f"{k}={v!r}" for k, v in values.items()) or "none"
    return text if len(text) <= limit else text[: limit - 3] + "..."


def _geometry(call: Any) -> Any:
    """Run a geometry call, turning the geometry layer's plain ValueErrors into typed errors."""
    try:
        return call()
    except GraceError:
        raise
    except ValueError as exc:
        raise ParameterError(str(exc)) from exc


def _dim(concept: Concept, joint: str) -> str:
    """The unit kind of a joint's value: a length for a prismatic joint, else an angle."""
    return "length" if concept.joints[joint]["kind"] == "prismatic" else "angle"

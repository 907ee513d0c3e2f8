"""Analysis by synthesis: a concept's parameters, joints and 6-DoF pose fitted to a partial cloud.

The loss is robust (Cauchy, scale ``CAUCHY``) in the compiled concept's signed distance at the
observed points, plus a free-space term: the camera saw through the space in front of every
point, so the surface must not come nearer along those rays (the distance at points a little
toward the camera must not be negative). A weak prior keeps parameters the view cannot see
(the back of a cabinet) near their start. Levenberg-Marquardt on exact derivatives (the
distance is one CasADi graph of parameters, joints and pose, ``perception.model``) minimizes
it; parameters stay in their typical ranges and joints in their limits (steps are projected),
and a step after which the concept's requirements fail is refused like one that raises the cost.

The start comes from ``init`` (a learned estimate) or from a coarse global search of its own:
similarity ICP of the cloud against the surface of the default instance, from rotations that
look at the concept's front from the upper hemisphere (a robot's usual view; ``pose_hint``
replaces them), lengths scaled by the ICP's scale.
"""

from __future__ import annotations

import math
from collections.abc import Mapping, Sequence
from dataclasses import dataclass, replace
from typing import Any

import numpy as np
from scipy.spatial import cKDTree

from grace_dsl.perception.camera import look_at
from grace_dsl.perception.labels import covered, label_masks, subsample
from grace_dsl.perception.model import (
    PartsModel,
    SdfModel,
    float_index,
    parts_model,
    sdf_model,
)
from grace_dsl.perception.outline import Outline, nearest_points, outline_rays
from grace_dsl.perception.start import feasible_instance, plane_starts, restarts
from grace_dsl.runtime.errors import ParameterError
from grace_dsl.runtime.instance import Instance
from grace_dsl.runtime.library import Concept
from grace_dsl.runtime.shapes import ShapeTree

CAUCHY = 0.004  # m: the robust scale (a 2 mm sensor's points lie well inside it)
# m: the scale a start is screened at first, so parts a few centimetres off still pull
WIDE_CAUCHY = 0.03
# m toward the camera from an observed point: free space (a handle standing off a front)
FREE_STEPS = tuple(np.geomspace(0.006, 0.12, 6).tolist())
FRONT_RAYS = 128
FREE_WEIGHT = 0.5
PRIOR_WEIGHT = 0.02  # per parameter, in units of its range
# with labels: a whole range's move costs what a 1 mm mean residual does, so the points move a
# part's parameters (0.02 outweighed a handle's 6 mm misfit) and only unseen ones stay put
LABEL_PRIOR = 0.001
SILHOUETTE = 4.0  # spacings: a ray farther than this from every observed ray saw nothing
FREE_RAYS = 200
FREE_DEPTHS = 12
ICP_POINTS = 256
SCREEN_ITERATIONS = 6  # per global start, before the best one is refined to the end
JOINT_STARTS = (0.0, 0.5, 0.9)  # of each joint's range
MODEL_POINTS = 1500
PLANE_STARTS = 5  # of the facing-plane starts, screened with the others
LEARNED_PLANES = 2  # of them screened against a learned start's pose
# m: with part labels a point's own part is where it belongs, so the first stage is nearly
# least squares: a handle 300 mm from its points still pulls (a 30 mm Cauchy scale would not)
LABEL_CAUCHY = 0.3
MIN_PART = 8  # points: a labelled part with fewer does not count in ``part_inliers``
#: the silhouette's rays: one camera's, several cameras' (fused looks) or none
Outlines = Outline | Sequence[Outline] | None
NOISE = 0.002  # m: the sensor noise a point's distance is read with (``Fitter.spread``)
# a step that lowers the cost by less than this share of it ends a stage: the last iterations
# of a converged stage cost a compiled Jacobian each and move the estimate by micrometres
CONVERGED = 1e-5


@dataclass(frozen=True)
class FitResult:
    """Where the fit ended: the instance in the frame of the points, and how well it fits."""

    params: dict[str, Any]  # every parameter, as ``Concept.instantiate`` takes them
    theta: np.ndarray  # the float entries of p
    joints: dict[str, float]
    pose: np.ndarray  # concept frame in the points' frame
    residual: float  # robust mean |distance| (m) of the points to the fitted surface
    inliers: float  # share of points within 3 CAUCHY of the surface
    iterations: int
    free: float = 0.0  # m: surface where the camera saw through, per observed point (robust)
    # with labels: the smallest share, over the labelled parts, of a part's points within
    # 3 CAUCHY of that part's own shapes (a fit turned 180 deg leaves the front's points off)
    part_inliers: float = 1.0
    # one standard deviation of each entry of theta (Gauss-Newton at the end: ``Fitter.spread``);
    # a parameter nothing in the view moves comes out at about its whole range
    spread: np.ndarray | None = None


def rotation_exp(w: np.ndarray) -> np.ndarray:
    """Rodrigues: the rotation by the rotation vector ``w``."""
    angle = float(np.linalg.norm(w))
    if angle < 1e-12:
        return np.eye(3)
    k = np.array([[0, -w[2], w[1]], [w[2], 0, -w[0]], [-w[1], w[0], 0]]) / angle
    return np.eye(3) + math.sin(angle) * k + (1 - math.cos(angle)) * (k @ k)


def _transform(m: np.ndarray, pts: np.ndarray) -> np.ndarray:
    return pts @ m[:3, :3].T + m[:3, 3]


def _inv(m: np.ndarray) -> np.ndarray:
    out = np.eye(4)
    out[:3, :3] = m[:3, :3].T
    out[:3, 3] = -m[:3, :3].T @ m[:3, 3]
    return out


# -- global initialization ------------------------------------------------------------------


def candidate_rotations(
    n_azimuth: int = 5, elevations: tuple[float, ...] = (20, 45)
) -> list[np.ndarray]:
    """Concept-in-camera rotations of cameras looking at the concept's front from the upper
    hemisphere (azimuth within +-60 deg of +z), as ``perception.views`` draws them."""
    out = []
    for e in elevations:
        for a in np.linspace(-60, 60, n_azimuth):
            er, ar = math.radians(e), math.radians(a)
            eye = np.array([math.cos(er) * math.sin(ar), math.sin(er), math.cos(er) * math.cos(ar)])
            out.append(_inv(look_at(eye, np.zeros(3)))[:3, :3])
    return out


def icp_similarity(
    data: np.ndarray, model: np.ndarray, tree: cKDTree, rot: np.ndarray, iterations: int = 20
) -> tuple[np.ndarray, float, float]:
    """Similarity ICP of ``data`` (points frame) onto ``model`` (concept frame) from ``rot``
    (concept in points frame): returns (pose: concept in points frame, scale of the concept,
    trimmed RMS distance). Each step matches every data point to its nearest model point
    (partial data against the whole model) and solves Umeyama's closed form."""
    r = rot.T  # points frame -> concept frame
    s = 1.0
    mc, dc = model.mean(axis=0), data.mean(axis=0)
    t = mc - r @ dc
    err = math.inf
    for _ in range(iterations):
        moved = s * (data @ r.T) + t
        dist, j = tree.query(moved)
        keep = dist <= np.quantile(dist, 0.9)
        a, b = data[keep], model[j[keep]]
        ma, mb = a.mean(axis=0), b.mean(axis=0)
        a0, b0 = a - ma, b - mb
        u, sv, vt = np.linalg.svd(b0.T @ a0)
        d = np.diag([1.0, 1.0, np.sign(np.linalg.det(u @ vt))])
        r = u @ d @ vt
        s = float(np.clip(np.trace(np.diag(sv) @ d) / (a0 * a0).sum(), 0.2, 5.0))
        t = mb - s * r @ ma
        err = float(np.sqrt(np.mean(dist[keep] ** 2)))
    # concept point x = s R p + t  ->  p = R^T (x - t) / s: concept (scaled by 1/s) in points frame
    pose = np.eye(4)
    pose[:3, :3] = r.T
    pose[:3, 3] = -r.T @ t / s
    return pose, 1.0 / s, err


def scaled_params(concept: Concept, base: Mapping[str, Any], scale: float) -> dict[str, Any]:
    """``base`` with every length multiplied by ``scale`` and clipped to its typical range."""
    out = dict(base)
    for s in concept.params:
        if s.kind in ("num", "vec") and s.dim == "length" and s.lo is not None:
            v = np.clip(np.asarray(base[s.name], float) * scale, s.lo, s.hi)
            out[s.name] = float(v) if s.kind == "num" else tuple(map(float, v))
    return out


def joint_starts(
    inst: Instance, fractions: tuple[float, ...] = JOINT_STARTS
) -> list[dict[str, float]]:
    """Joint states to start from: every joint at each fraction of its range (closed first)."""
    limits = inst.joint_limits()
    if not limits:
        return [{}]
    out = []
    for f in fractions:
        out.append(
            {
                n: float(max(lo, -math.pi) + f * (min(hi, math.pi) - max(lo, -math.pi)))
                for n, (lo, hi) in limits.items()
            }
        )
    return out


def global_init(
    concept: Concept,
    points: np.ndarray,
    base: Mapping[str, Any] | None = None,
    rotations: list[np.ndarray] | None = None,
    seed: int = 0,
    joints: Mapping[str, float] | None = None,
) -> list[tuple[float, np.ndarray, dict[str, Any], dict[str, float]]]:
    """Starts for the fit, best first: (ICP error, pose, parameters, joints)."""
    base = concept.instantiate().params if base is None else dict(base)
    inst = concept.instantiate(params=base)
    rng = np.random.default_rng(seed)
    data = points[rng.choice(len(points), min(ICP_POINTS, len(points)), replace=False)]
    starts = []
    for state in [dict(joints)] if joints else joint_starts(inst):
        model = (
            inst.with_joints(state).sample_surface(MODEL_POINTS, seed=seed)
            if state
            else (inst.sample_surface(MODEL_POINTS, seed=seed))
        )
        tree = cKDTree(model)
        for rot in candidate_rotations() if rotations is None else rotations:
            pose, scale, err = icp_similarity(data, model, tree, rot)
            starts.append((err / scale, pose, scaled_params(concept, base, scale), state))
    starts.sort(key=lambda s: s[0])
    return starts


# -- free space ------------------------------------------------------------------------------


def free_space(
    points: np.ndarray,
    camera: np.ndarray,
    seed: int = 0,
    margin: float = 0.3,
    grid: int = 50,
    silhouette: float = SILHOUETTE,
    n_rays: int = FREE_RAYS,
) -> np.ndarray:
    """Points the camera saw through, where the fitted surface must not be: a little in front
    of every observed point, and along the rays just outside the cloud's outline (rays that met
    nothing within the cloud's depth range: the silhouette). The outline is read off the rays'
    gnomonic projection, which needs no intrinsics: a ray is free when no observed ray lies
    within ``SILHOUETTE`` times their typical spacing. The outline's rays are drawn within
    ``margin`` times the cloud's extent of it, on a grid of ``grid`` steps across the extent
    (finer: the seen-through band starts nearer the outline, which a dense cloud allows, as
    does a ``silhouette`` of fewer spacings), ``n_rays`` of them."""
    rays = points - camera
    dist = np.linalg.norm(rays, axis=1)
    unit = rays / np.maximum(dist, 1e-9)[:, None]
    rng = np.random.default_rng(seed)
    some = rng.choice(len(points), min(FRONT_RAYS, len(points)), replace=False)
    # each ray's steps jittered within their geometric spacing: together the rays cover every
    # depth in front of the points, not six fixed ones a thin bar can sit between
    ratio = FREE_STEPS[1] / FREE_STEPS[0]
    jitter = ratio ** rng.uniform(-0.5, 0.5, (len(FREE_STEPS), len(some)))
    front = [points[some] - (s * j)[:, None] * unit[some] for s, j in zip(FREE_STEPS, jitter)]
    c = unit.mean(axis=0)
    c /= np.linalg.norm(c)
    e1 = np.cross(c, [0.0, 1.0, 0.0] if abs(c[1]) < 0.9 else [1.0, 0.0, 0.0])
    e1 /= np.linalg.norm(e1)
    e2 = np.cross(c, e1)
    cos = unit @ c
    if np.any(cos < 0.2):  # the cloud spans too wide a view for one projection
        return np.concatenate(front)
    a = np.stack([unit @ e1 / cos, unit @ e2 / cos], axis=1)
    tree = cKDTree(a)
    spacing = float(np.median(tree.query(a, k=2)[0][:, 1]))
    lo, hi = a.min(axis=0), a.max(axis=0)
    pad = margin * (hi - lo) + 4 * spacing
    step = max(spacing, float((hi - lo).max()) / grid)
    gu = np.arange(lo[0] - pad[0], hi[0] + pad[0], step)
    gv = np.arange(lo[1] - pad[1], hi[1] + pad[1], step)
    cells = np.stack(np.meshgrid(gu, gv), -1).reshape(-1, 2)
    free = cells[tree.query(cells)[0] > silhouette * max(spacing, step / 2)]
    if len(free) > n_rays:
        free = free[rng.choice(len(free), n_rays, replace=False)]
    dirs = c + free[:, :1] * e1 + free[:, 1:] * e2
    dirs /= np.linalg.norm(dirs, axis=1, keepdims=True)
    extent = float(np.linalg.norm(points.max(axis=0) - points.min(axis=0)))
    depths = np.linspace(dist.min() - 0.3 * extent, dist.max() + 0.3 * extent, FREE_DEPTHS)
    along = camera + (dirs[:, None, :] * depths[None, :, None]).reshape(-1, 3)
    return np.concatenate([*front, along])


# -- local refinement -----------------------------------------------------------------------


@dataclass
class _State:
    theta: np.ndarray
    q: np.ndarray
    pose: np.ndarray
    cost: float = math.inf


class Fitter:
    """Levenberg-Marquardt on one concept with its discrete parameters fixed."""

    def __init__(
        self,
        concept: Concept,
        params: Mapping[str, Any],
        joints: Mapping[str, float],
        cauchy: float = CAUCHY,
        labels: np.ndarray | None = None,
        strict: bool = True,
    ):
        """``labels`` (N,) part names of the points ``run`` will get (``perception.labels``):
        each point is then measured against its own part's shapes. ``strict``: refuse steps
        that break a requirement, and start from ``params`` made feasible; otherwise start
        from ``params`` as they are and let the iterates cross requirements."""
        self.concept, self.cauchy, self.strict = concept, cauchy, strict
        self.prior = PRIOR_WEIGHT if labels is None else LABEL_PRIOR
        inst = feasible_instance(concept, params)
        if joints:
            inst = inst.with_joints(dict(joints))
        self.pfix = inst.p.copy()
        if not strict:
            idx = list(float_index(concept))
            self.pfix[idx] = concept.pack(dict(params))[idx]
        shapes = tuple(ShapeTree(inst).shapes)
        self.model: SdfModel | PartsModel
        self.masks: np.ndarray | None = None
        self.labels = labels
        if labels is None:
            self.model = sdf_model(concept, shapes)
        else:
            self.model = parts_model(concept, shapes)
            self.masks = label_masks(labels, self.model.shapes, self.model.links, concept.name)
        idx = list(self.model.float_index)
        lo, hi = [], []
        for s in concept.params:
            if s.kind in ("num", "vec"):
                lo += list(np.atleast_1d(s.lo))
                hi += list(np.atleast_1d(s.hi))
        self.lo, self.hi = np.array(lo, float), np.array(hi, float)
        self.span = np.maximum(self.hi - self.lo, 1e-6)
        self.theta0 = self.pfix[idx].copy()
        self.q0 = inst.q.copy()
        self.present = [concept.joint_index[n] for n in inst.joints]

    def _p(self, theta: np.ndarray) -> np.ndarray:
        p = self.pfix.copy()
        p[list(self.model.float_index)] = theta
        return p

    def feasible(self, theta: np.ndarray) -> bool:
        held = np.asarray(self.concept.function("instance_checks")(self._p(theta))[0]).ravel()
        return bool(np.all(held == 1.0))

    def limits(self, theta: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        lo, hi = self.concept.function("joint_limits")(self._p(theta))
        lo, hi = np.asarray(lo, float).ravel(), np.asarray(hi, float).ravel()
        return np.maximum(lo, -math.pi), np.minimum(hi, math.pi)

    def residuals(
        self, st: _State, y: np.ndarray, free: np.ndarray, with_jac: bool
    ) -> tuple[np.ndarray, np.ndarray | None, np.ndarray]:
        """Weighted residuals (and Jacobian) of data, free-space and prior terms at ``st``, with
        the points already in the frame of ``st.pose``; the third output is the data distances."""
        n = len(y)
        active = None
        if with_jac:  # a free-space point weighs only where the surface reaches it
            active = self.distances(st, free, False)[0] < 0
            free = free[active]
        d, g = self.distances(st, np.concatenate([y, free]), with_jac, n)
        if active is not None and g is not None:
            d, g = _rows(d, active, n, 0.0), _rows(g, active, n, 0.0)
        dd, df = d[:n], d[n:]
        # Cauchy as IRLS: sqrt of the weight times the distance
        wd = 1.0 / np.sqrt(1.0 + (dd / self.cauchy) ** 2)
        wf = FREE_WEIGHT * (df < 0)
        scale = 1.0 / math.sqrt(n)
        prior = self.prior * (st.theta - self.theta0) / self.span
        r = np.concatenate([scale * wd * dd, scale * wf * df, prior])
        jac = None
        if g is not None:
            jp = np.zeros((len(prior), g.shape[1]))
            jp[:, : len(prior)] = np.diag(self.prior / self.span)
            jac = np.concatenate([scale * wd[:, None] * g[:n], scale * wf[:, None] * g[n:], jp])
        return r, jac, dd

    def distances(
        self, st: _State, pts: np.ndarray, with_jac: bool, labelled: int = 0
    ) -> tuple[np.ndarray, np.ndarray | None]:
        """Distance (and its gradient) of the surface at ``pts`` (in the frame of ``st.pose``):
        the first ``labelled`` points to their own part's shapes, the rest to every shape."""
        m, pfix, w0 = self.model, self._p(st.theta), np.zeros(6)
        if isinstance(m, SdfModel):
            if with_jac:
                d, g = m.gradient.batch(st.theta, pfix, st.q, w0, pts)
                return np.asarray(d).reshape(-1), np.asarray(g).reshape(len(pts), -1)
            return np.asarray(m.value.batch(st.theta, pfix, st.q, w0, pts)).reshape(-1), None
        assert self.masks is not None
        # every shape's distance, then only the shape each point is measured against is
        # differentiated (its own part's nearest for a labelled point, the union's for the rest)
        d = m.distances(st.theta, pfix, st.q, w0, pts)
        own = np.where(self.masks[:labelled], d[:labelled], np.inf)
        k = np.concatenate([own.argmin(axis=1), d[labelled:].argmin(axis=1)])
        if not with_jac:
            return d[np.arange(len(pts)), k], None
        return m.gradients(st.theta, pfix, st.q, w0, pts, k)

    def run(
        self,
        points: np.ndarray,
        pose: np.ndarray,
        camera: np.ndarray,
        iterations: int = 30,
        free: np.ndarray | None = None,
        outline: Outlines = None,
    ) -> FitResult:
        """Refine from ``pose`` (concept in the points' frame) and the starting parameters;
        ``free`` the free-space points (``free_space``: computed here when None); ``outline``
        rays outside the silhouette (``perception.outline``): each one's nearest point to the
        estimate joins the free space, searched again after every accepted step."""
        st = _State(self.theta0.copy(), self.q0.copy(), pose.copy())
        free_static = free_space(points, camera) if free is None else free
        free_world = self._with_outline(st, free_static, outline)
        mu, nt, nq = 1e-3, len(st.theta), len(st.q)
        frame = _inv(st.pose)
        y, f = _transform(frame, points), _transform(frame, free_world)
        r, jac, dd = self.residuals(st, y, f, True)
        st.cost = float(r @ r)
        done = 0
        for it in range(1, iterations + 1):
            done = it
            assert jac is not None
            jtj, jtr = jac.T @ jac, jac.T @ r
            diag = np.maximum(np.diag(jtj), 1e-12)
            for _ in range(8):
                step = -np.linalg.solve(jtj + mu * np.diag(diag), jtr)
                if self.masks is not None:
                    step = self._bounded(st, step, jtj + mu * np.diag(diag), jtr)
                trial = self._step(st, step, nt, nq)
                if trial is None and self.masks is not None:
                    trial = self._shortened(st, step, nt, nq)
                if trial is not None:
                    frame = _inv(trial.pose)
                    y, f = _transform(frame, points), _transform(frame, free_world)
                    r2, _, _ = self.residuals(trial, y, f, False)
                    trial.cost = float(r2 @ r2)
                    if trial.cost < st.cost:
                        break
                mu *= 10
            else:
                break
            gain = st.cost - trial.cost
            st, mu = trial, max(mu / 3, 1e-7)
            if outline is not None:
                free_world = self._with_outline(st, free_static, outline)
                f = _transform(_inv(st.pose), free_world)
            r, jac, dd = self.residuals(st, y, f, True)
            st.cost = float(r @ r)
            if gain < CONVERGED * max(st.cost, 1e-12):
                break
        # r, jac and dd are those at st (the last accepted step's points and free space)
        df = r[len(dd) : len(r) - len(st.theta)] * math.sqrt(len(dd))
        seen = float(np.sum(np.minimum(np.maximum(-df / FREE_WEIGHT, 0.0), 3 * CAUCHY)))
        assert jac is not None
        return replace(
            self._result(st, dd, done),
            free=FREE_WEIGHT * seen / len(points),
            part_inliers=self._parts(dd),
            spread=self.spread(jac, len(r) - len(st.theta), len(dd)),
        )

    def spread(self, jac: np.ndarray, rows: int, n: int) -> np.ndarray:
        """One standard deviation of each entry of theta, by Gauss-Newton: the information of
        the data and free-space rows of ``jac`` (``residuals``, ``n`` data points) at a sensor
        noise of ``NOISE``, plus one range's worth of prior per parameter, so a parameter the
        view cannot move (a drawer's travel, the depth behind a closed front) comes out at
        about its range instead of looking as sure as the rest."""
        a = jac[:rows] * (math.sqrt(n) / NOISE)
        info = a.T @ a
        nt = len(self.theta0)
        info[:nt, :nt] += np.diag(1.0 / self.span**2)
        info[nt:, nt:] += np.eye(info.shape[0] - nt) * 1e-6  # pose and joints: keep it regular
        cov = np.linalg.pinv(info)
        return np.sqrt(np.maximum(np.diag(cov)[:nt], 0.0))

    def _with_outline(self, st: _State, free: np.ndarray, outline: Outlines) -> np.ndarray:
        """``free`` and, per outline ray, its point nearest the surface at ``st`` (the rays of
        every camera, when the points come from several)."""
        if outline is None:
            return free
        frame = _inv(st.pose)

        def union(world: np.ndarray) -> np.ndarray:
            return self.distances(st, _transform(frame, world), False)[0]

        rays = [outline] if isinstance(outline, Outline) else list(outline)
        return np.concatenate([free, *(nearest_points(o, union, OUTLINE_DEPTHS) for o in rays)])

    def _parts(self, dd: np.ndarray) -> float:
        """The worst labelled part's share of points on its own shapes (1 without labels);
        parts with fewer than ``MIN_PART`` points do not count."""
        if self.labels is None:
            return 1.0
        near = np.abs(dd) < 3 * CAUCHY
        shares = [
            float(near[self.labels == n].mean())
            for n in np.unique(self.labels)
            if (self.labels == n).sum() >= MIN_PART
        ]
        return min(shares, default=1.0)

    def _step(self, st: _State, step: np.ndarray, nt: int, nq: int) -> _State | None:
        theta = np.clip(st.theta + step[:nt], self.lo, self.hi)
        if self.strict and not self.feasible(theta):
            return None
        q = st.q.copy()
        if nq:
            lo, hi = self.limits(theta)
            q = np.clip(st.q + step[nt : nt + nq], lo, hi)
        w = step[nt + nq :]
        delta = np.eye(4)
        delta[:3, :3], delta[:3, 3] = rotation_exp(w[:3]), w[3:]
        return _State(theta, q, st.pose @ delta)

    def _bounded(
        self, st: _State, step: np.ndarray, system: np.ndarray, rhs: np.ndarray
    ) -> np.ndarray:
        """The step solved again with the parameters it would push past their range held
        (an active set): clipping them afterwards turns the step into one that need not
        descend, and the fit then stalls with a thickness at its bound."""
        nt = len(st.theta)
        held = np.zeros(len(step), bool)
        held[:nt] = ((st.theta <= self.lo + 1e-9) & (step[:nt] < 0)) | (
            (st.theta >= self.hi - 1e-9) & (step[:nt] > 0)
        )
        if not held.any():
            return step
        a, b = system.copy(), rhs.copy()
        a[held, :], a[:, held], b[held] = 0.0, 0.0, 0.0
        a[held, held] = 1.0
        return -np.linalg.solve(a, b)

    def _shortened(self, st: _State, step: np.ndarray, nt: int, nq: int) -> _State | None:
        """A step whose parameters break a requirement, with its parameter part shortened
        until they hold (pose and joints move in full): the labelled fit's parameters travel
        far and would otherwise stop at the first requirement they meet."""
        for t in (0.5, 0.25, 0.1, 0.0):
            short = step.copy()
            short[:nt] *= t
            trial = self._step(st, short, nt, nq)
            if trial is not None:
                return trial
        return None

    def _result(self, st: _State, dd: np.ndarray, iterations: int) -> FitResult:
        p = self._p(st.theta)
        params = {s.name: s.decode(p[s.offset : s.offset + s.size]) for s in self.concept.params}
        names = self.concept.moving_joints
        joints = {names[i]: float(st.q[i]) for i in self.present}
        a = np.abs(dd)
        robust = float(np.mean(np.minimum(a, 3 * CAUCHY)))  # far outliers count as 3 scales
        return FitResult(
            params,
            st.theta.copy(),
            joints,
            st.pose,
            robust,
            float(np.mean(a < 3 * CAUCHY)),
            iterations,
        )


def _rows(a: np.ndarray, active: np.ndarray, n: int, fill: float) -> np.ndarray:
    """``a`` (n data rows, then the free-space rows where ``active``) with ``fill`` in the free
    rows that were not evaluated."""
    out = np.full((n + len(active), *a.shape[1:]), fill)
    out[:n] = a[:n]
    out[n:][active] = a[n:]
    return out


def fit(
    concept: Concept,
    points: np.ndarray,
    *,
    camera: np.ndarray | None = None,
    pose_hint: np.ndarray | None = None,
    init: Mapping[str, Any] | None = None,
    init_joints: Mapping[str, float] | None = None,
    starts: int = 6,
    iterations: int = 20,
    seed: int = 0,
    facing: bool = True,
    labels: np.ndarray | None = None,
) -> FitResult:
    """Fit ``concept`` to ``points`` (N, 3): the best of ``starts`` refinements.

    ``camera`` is the camera's position in the points' frame (default the origin: points in the
    camera frame), ``pose_hint`` a 4x4 concept pose to start from (skips the rotation search),
    ``init`` parameter values to start from (a learned estimate: every parameter, or some);
    ``facing`` adds the starts of ``perception.start`` (the front's plane gives the rotation)
    for points in a level camera's frame. ``labels`` (N,) part names (``perception.labels``)
    measure each point against its own part (``labelled_fit``)."""
    if labels is not None:
        return labelled_fit(
            concept,
            points,
            labels,
            camera=camera,
            pose_hint=pose_hint,
            init=init,
            init_joints=init_joints,
            iterations=iterations,
            seed=seed,
            facing=facing,
        )
    base = concept.instantiate().params
    if init:
        base.update(init)
    cam = np.zeros(3) if camera is None else np.asarray(camera, float)
    hint = None if pose_hint is None else np.asarray(pose_hint, float)
    inst = feasible_instance(concept, base)
    states = [dict(init_joints)] if init_joints else joint_starts(inst)
    planes = (
        plane_starts(concept, points, inst.params, states, camera, seed)
        if facing and camera is None
        else []
    )
    if hint is not None and init:
        # the learned pose first, then the planes' rotations with the learned parameters
        cands = [(0.0, hint, base, dict(init_joints or {}))] + planes[:LEARNED_PLANES]
    else:
        rots = None if hint is None else [hint[:3, :3]]
        icp = global_init(concept, points, base, rots, seed, init_joints)
        cands = planes[:PLANE_STARTS] + icp[: max(starts - min(len(planes), PLANE_STARTS), 1)]
    tried: list[FitResult] = []
    short = iterations if len(cands) == 1 else SCREEN_ITERATIONS
    for _, pose, params, joints in cands[:starts]:
        try:
            fitter = Fitter(concept, params, joints, WIDE_CAUCHY)
        except ParameterError:  # a scaled start that breaks a requirement
            fitter = Fitter(concept, base, joints, WIDE_CAUCHY)
        wide = fitter.run(points, pose, cam, short)
        tried.append(Fitter(concept, wide.params, wide.joints).run(points, wide.pose, cam, short))
    best = min(tried, key=_score)
    if short < iterations:  # continue the best screened start
        best = Fitter(concept, best.params, best.joints).run(points, best.pose, cam, iterations)
    return best


# of the robust residual: a labelled part whose points all lie off its shapes costs what a
# 10 mm mean residual does
PART_WEIGHT = 0.01
LABEL_SCREEN = 5  # near-least-squares iterations per labelled start before the best is kept
LABEL_PLANES = 3  # facing-plane starts screened with labels (one per plane)
LEARNED_OWN = LABEL_PLANES + 2  # of the fit's own starts screened beside a learned one
LABEL_POINTS = 384  # the labelled fit's points (every part keeps a share: ``subsample``)
LABEL_FREE = 768  # and free-space points
LABEL_MARGIN = 0.1  # of the extent: the band outside the outline the free rays are drawn in
OUTLINE = True  # the silhouette's render-and-compare term (``perception.outline``)
# m: the Cauchy scales the outline term joins at; the near-least-squares stages place the parts
# first (from a far start every ray cuts the surface, and their pull squeezed the handle)
OUTLINE_SCALE = WIDE_CAUCHY
OUTLINE_DEPTHS = 16  # per outline ray and search (coarse, then as many within one step): 24
# cost a fifth more CPU per part for the same errors (HingedCabinet, Refrigerator, Microwave)


def labelled_fit(
    concept: Concept,
    points: np.ndarray,
    labels: np.ndarray,
    *,
    camera: np.ndarray | None = None,
    pose_hint: np.ndarray | None = None,
    init: Mapping[str, Any] | None = None,
    init_joints: Mapping[str, float] | None = None,
    iterations: int = 20,
    seed: int = 0,
    facing: bool = True,
    views: Sequence[tuple[np.ndarray, np.ndarray]] | None = None,
    starts: Sequence[tuple[np.ndarray, Mapping[str, Any], Mapping[str, float]]] = (),
) -> FitResult:
    """The fit with every point measured against its own part's shapes. Its loss pulls each
    part to its own points from anywhere (the first stage is nearly least squares), so few
    starts are needed and the joints come from the labelled links: the learned or hinted pose,
    one start per facing plane and the discrete variants of the best, or one ICP start when no
    plane faces the camera; with a learned start, the fit's own facing starts beside it (a
    network's wrong size or pose must beat them). Each is screened by ``LABEL_SCREEN``
    iterations of the first stage (ranked with the worst part's inliers, ``_label_score``);
    the best finishes that stage, is screened against its known local minima (``_restarted``)
    and goes on through the narrower scales.

    ``views``: when ``points`` joins the clouds of several cameras (fused looks, one frame),
    each camera's own cloud and position, (points (M, 3), camera (3,)): free space and the
    outline are read per camera (what one camera saw through, another may not have seen), the
    data term takes every point, ``LABEL_POINTS`` per camera. ``starts``: more starts to
    screen, (pose, parameters, joints) each (single looks' fits, in the points' frame)."""
    rng = np.random.default_rng(seed)
    cam = np.zeros(3) if camera is None else np.asarray(camera, float)
    seen = [(points, cam)] if views is None else [(np.asarray(p), np.asarray(c)) for p, c in views]
    # the outline from every point: a subsample's wider spacing would start the seen-through
    # space centimetres outside it (4 spacings), where a too tall cabinet is not caught
    frees = [free_space(p, c, seed, LABEL_MARGIN) for p, c in seen]
    outline = _outlines(seen, seed) if OUTLINE else None
    keep = subsample(labels, LABEL_POINTS * len(seen), rng)
    points, labels = points[keep], labels[keep]
    base = concept.instantiate().params
    if init:
        base.update(init)
    base = labelled_variant(concept, base, labels)
    hint = None if pose_hint is None else np.asarray(pose_hint, float)
    free = np.concatenate([_thinned(f, LABEL_FREE, rng) for f in frees])
    inst = feasible_instance(concept, base)
    states = [dict(init_joints)] if init_joints else joint_starts(inst)[:1]
    cands: list[tuple[float, np.ndarray, dict[str, Any], dict[str, float]]] = []
    if hint is not None:
        cands.append((0.0, hint, base, states[0]))
    for pose, params, joints in starts:
        cands.append((0.0, np.asarray(pose, float), base | dict(params), dict(joints)))
    if facing and camera is None and views is None:  # a hint is screened against the planes too
        planes = plane_starts(concept, points, inst.params, states, camera, seed, draws=0)
        cands += planes[: LEARNED_PLANES if hint is not None else LABEL_PLANES + 2]
        if init:  # the fit's own starts too: a network's wrong size or pose must not win alone
            own = labelled_variant(concept, concept.instantiate().params, labels)
            own_states = joint_starts(feasible_instance(concept, own))[:1]
            cands += plane_starts(concept, points, own, own_states, camera, seed, draws=0)[
                :LEARNED_OWN
            ]
    if not cands:
        rots = None if hint is None else [hint[:3, :3]]
        cands = global_init(concept, points, base, rots, seed, init_joints)[:2]
    tried = []
    for _, pose, params, joints in cands:
        if not _resolves(concept, params, [str(n) for n in np.unique(labels)]):
            continue  # a variant without the labelled parts (another handle kind)
        tried.append(
            _stage(concept, points, labels, free, outline, pose, params, joints, LABEL_CAUCHY)
        )
    if not tried:  # every start lost a labelled part: start from the labels' own variant
        tried.append(
            _stage(concept, points, labels, free, outline, cands[0][1], base, states[0], 0.3)
        )
    best = min(tried, key=_label_score)
    best = _resume(concept, points, labels, free, outline, best, LABEL_CAUCHY, 15)
    best = _restarted(concept, points, labels, free, outline, best)
    best = _resume(concept, points, labels, free, outline, best, WIDE_CAUCHY, LABEL_SCREEN)
    # the last stage keeps the requirements (a real instance meets them), from the nearest
    # start that meets them: the earlier stages may cross them on the way (a height and a
    # handle's place move together), which a strict fit's refused steps could not
    params = dict(feasible_instance(concept, best.params).params)
    return _stage(
        concept,
        points,
        labels,
        free,
        outline,
        best.pose,
        params,
        best.joints,
        CAUCHY,
        iterations,
        True,
    )


def _restarted(
    concept: Concept,
    points: np.ndarray,
    labels: np.ndarray,
    free: np.ndarray,
    outline: Outlines,
    best: FitResult,
) -> FitResult:
    """``best`` (after the first stage) or a restart from it that screens lower: the known
    local minima of the first stage (``perception.start.restarts``), each given
    ``LABEL_SCREEN`` iterations of the first stage; a winner gets the rest of that stage."""
    tried = [best]
    for pose, params, joints in restarts(concept, best.pose, best.params, best.joints):
        tried.append(
            _stage(concept, points, labels, free, outline, pose, params, joints, LABEL_CAUCHY)
        )
    won = min(tried, key=_label_score)
    if won is best:
        return best
    return _resume(concept, points, labels, free, outline, won, LABEL_CAUCHY, 15 - LABEL_SCREEN)


def _thinned(pts: np.ndarray, n: int, rng: np.random.Generator) -> np.ndarray:
    """At most ``n`` of ``pts``, drawn without replacement."""
    return pts if len(pts) <= n else pts[rng.choice(len(pts), n, replace=False)]


def _outlines(seen: Sequence[tuple[np.ndarray, np.ndarray]], seed: int) -> Outlines:
    """The silhouette's rays of each camera (one camera: its ``Outline`` or None)."""
    rays = [outline_rays(p, c, seed) for p, c in seen]
    if len(rays) == 1:
        return rays[0]
    return [r for r in rays if r is not None] or None


def _resolves(concept: Concept, params: Mapping[str, Any], names: list[str]) -> bool:
    """Whether every label names shapes of the instance at ``params``."""
    inst = feasible_instance(concept, params)
    tree = ShapeTree(inst)
    shapes = tree.outermost()
    links = [tree.shapes[n]["link"] for n in shapes]
    return all(covered(n, shapes, links).any() for n in names)


def labelled_variant(
    concept: Concept, params: Mapping[str, Any], labels: np.ndarray
) -> dict[str, Any]:
    """``params`` with the discrete values the labels call for: a label that names a part
    only another variant has (``handle@curved.bar`` when the start has a bar handle) picks
    that variant, which the fit cannot change. Unresolvable labels raise ``LabelError``."""
    names = [str(n) for n in np.unique(labels)]
    if _resolves(concept, params, names):
        return dict(params)
    for s in concept.params:
        values = list(s.choices or ()) if s.kind == "choice" else [True, False]
        if s.kind not in ("choice", "bool"):
            continue
        for v in values:
            other = dict(params) | {s.name: v}
            try:
                if _resolves(concept, other, names):
                    return dict(feasible_instance(concept, other).params)
            except ParameterError:
                continue
    inst = feasible_instance(concept, params)
    tree = ShapeTree(inst)
    shapes = tree.outermost()
    label_masks(labels, shapes, [tree.shapes[n]["link"] for n in shapes], concept.name)
    return dict(params)  # not reached: label_masks raised


def _stage(
    concept: Concept,
    points: np.ndarray,
    labels: np.ndarray,
    free: np.ndarray,
    outline: Outlines,
    pose: np.ndarray,
    params: Mapping[str, Any],
    joints: Mapping[str, float],
    scale: float,
    iterations: int = LABEL_SCREEN,
    strict: bool = False,
) -> FitResult:
    """A labelled fit at one robust scale from one start (``strict``: see ``Fitter``)."""
    try:
        fitter = Fitter(concept, params, joints, scale, labels, strict)
    except ParameterError:  # a scaled start that breaks a requirement
        fitter = Fitter(concept, concept.instantiate().params, joints, scale, labels, strict)
    seen = outline if scale <= OUTLINE_SCALE else None
    return fitter.run(points, pose, np.zeros(3), iterations, free, seen)


def _resume(
    concept: Concept,
    points: np.ndarray,
    labels: np.ndarray,
    free: np.ndarray,
    outline: Outlines,
    fit: FitResult,
    scale: float,
    iterations: int,
) -> FitResult:
    """``_stage`` started where ``fit`` ended: its pose, parameters and joints."""
    return _stage(
        concept, points, labels, free, outline, fit.pose, fit.params, fit.joints, scale, iterations
    )


def _label_score(r: FitResult) -> float:
    """``_score`` plus the share of the worst labelled part's points off its own shapes: a
    start that ends with the door's points on the cabinet (a flip, the hinge's wrong side) fits
    the rest as well as the right one, but a part's points far from its part mark it."""
    return _score(r) + PART_WEIGHT * (1 - r.part_inliers)


def _score(r: FitResult) -> float:
    """Lower is better: the points' robust distance, surface in seen-through space, outliers."""
    return r.residual + r.free + 0.01 * (1 - r.inliers)


def fitted_instance(concept: Concept, result: FitResult) -> Instance:
    """The fitted instance, posed in the points' frame."""
    inst = concept.instantiate(params=result.params, pose=result.pose)
    return inst.with_joints(result.joints) if result.joints else inst


def fitted_instance_of(concept: Concept, est: Any) -> Instance:
    """The instance an ``Estimate`` describes, posed in the points' frame."""
    from grace_dsl.perception.views import join_params

    defaults = concept.instantiate().params  # the non-float ones an Estimate does not carry
    chosen = getattr(est, "discrete", {})
    fixed = {
        s.name: chosen.get(s.name, defaults[s.name])
        for s in concept.params
        if s.kind not in ("num", "vec")
    }
    inst = concept.instantiate(params=join_params(concept, est.params, fixed), pose=est.pose)
    return inst.with_joints(est.joints) if est.joints else inst

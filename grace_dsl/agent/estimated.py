"""The ``estimated`` mode: the agent's model of an object from the simulated RGB-D camera.

Why this lives in the agent layer: it needs the simulator's camera (``grace_dsl.sim``) and
perception's estimator (``grace_dsl.perception``), and neither of those may import the other.

One look (``look``): the world is rendered by MuJoCo from a camera placed on the upper
hemisphere about the object (azimuth, elevation; the protocol's or the agent's own choice), the
depth gets a seeded Gaussian sensor noise (sigma 2 mm, as perception's benchmark), the object's
pixels are picked by a ``Segmenter`` (default: ``GroundTruthSegmenter`` on the renderer's body
labels, asked for the object's concept by name) and back-projected into the camera frame
(OpenCV axes, as perception's clouds). ``eac.estimate`` then fits the concept, started from the
shipped learned network's estimate where the concept has weights. The result (``Perceived``) is
the concept's parameters, its WORLD pose (camera pose times the estimate's camera-frame pose),
its joints, the residual and the confidence.

A look whose confidence is below ``MIN_CONFIDENCE`` is refused (``EstimateRefused``, a typed
error carrying the estimate): the agent never acts on a model it does not trust; the caller takes
another view or reports the refusal. Parameters perception does not estimate (integers, choices,
flags: the concept's structure) are given (``fixed_params``: the scene's or the draw's, else the
concept's defaults) and held fixed in the fit.

Several looks (``fuse``): every look keeps its labelled cloud in the world frame with its
camera (``Sight.cloud``); from the second look on, all the looks taken are fitted at once
(``eac.estimate(..., looks=)``: one set of parameters, each camera's free space and outline),
started from the single looks' fits, and that estimate is refused or accepted like one look's.
"""

from __future__ import annotations

import math
from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field, replace
from typing import TYPE_CHECKING, Any

import numpy as np

from grace_dsl.perception.camera import DepthNoise, back_project
from grace_dsl.perception.errors import PerceptionError
from grace_dsl.perception.looks import Look
from grace_dsl.perception.render import DepthRender
from grace_dsl.perception.segment import GroundTruthSegmenter
from grace_dsl.perception.types import Estimate, Intrinsics, Segmenter
from grace_dsl.runtime.errors import ParameterError
from grace_dsl.sim.camera import Camera
from grace_dsl.sim.scene import Frame, Scene

if TYPE_CHECKING:
    import mujoco

    from grace_dsl.agent.plan import SceneObject
    from grace_dsl.runtime.instance import Instance
    from grace_dsl.runtime.library import Concept
    from grace_dsl.sim.multi import MultiWorld

MIN_CONFIDENCE = 0.7  # below this an estimate is refused, never acted on (measured)
NOISE = 0.002  # m: the depth sensor's Gaussian sigma
#: OpenCV camera axes (x right, y down, z forward) from MuJoCo's (x right, y up, z backward)
CV = np.diag([1.0, -1.0, -1.0, 1.0])
FRAMING = 3.0  # the camera stands this many bounding radii from the object's centre
IMAGE = (320, 240)  # pixels (width, height)
PART = "handle"  # the part whose pixels a look counts (the part most grasps hold)
MIN_PART_POINTS = 16  # fewer handle pixels: the handle is not in view, the look is refused
LOOKS = 3  # at most this many looks per episode: the protocol's and two the agent chooses
SAME_VIEW = 20.0  # degrees: a view this near one already taken would show nothing new
#: degrees: the protocol's camera band (upper hemisphere); every look the agent chooses stays in it
ELEVATIONS = (30.0, 60.0)
LOW_ELEVATION = ELEVATIONS[0]  # where a look goes when no look has shown the handle from above
#: degrees: the highest a chosen look goes (a front is a vertical face: from high above it is
#: foreshortened, and the looks refused at confidence ~0 were mostly taken from 46-60 deg)
HIGH_ELEVATION = 45.0
#: a refused fit at least this confident says where the front is (below: its front is noise)
FRONT_TRUST = 0.3


class EstimateRefused(PerceptionError):
    """The estimate's confidence is below the agent's threshold: acting on it would be a guess.

    ``estimate`` holds the refused estimate (its residual and confidence say why); take another
    view, or lower ``min_confidence`` knowingly."""

    def __init__(
        self, message: str, perceived: Perceived | None = None, sight: Sight | None = None
    ):
        super().__init__(message)
        self.perceived = perceived
        self.sight = sight if sight is not None else perceived.sight if perceived else None


@dataclass(frozen=True)
class View:
    """Where the camera looks from: azimuth and elevation (degrees) about the object."""

    azimuth: float
    elevation: float

    def opposite(self) -> View:
        """The view from the other side of the object (azimuth + 180 degrees)."""
        return View((self.azimuth + 180.0) % 360.0, self.elevation)


@dataclass(frozen=True)
class Sight:
    """What a look showed in the world frame, for choosing the next view: where the handle's
    pixels were (their centroid, None if none were seen), where the estimated front points
    (the fitted concept's +z, None when no fit ran) and how many of the handle's pixels it
    saw (-1: the concept has no handle)."""

    view: View
    centre: tuple[float, float, float]  # where the camera was aimed
    handle_at: tuple[float, float, float] | None = None
    front: tuple[float, float, float] | None = None
    handle: int = -1  # the handle's pixels seen (-1: the concept has none)
    # the look's labelled cloud in the world frame with its camera: what a fused fit takes
    cloud: Look | None = field(default=None, compare=False, repr=False)
    held: int = -1  # pixels of the link the task moves (-1: not asked for)
    confidence: float = 1.0  # the fit's whose front this is (1.0: given, not fitted)
    fused: bool = False  # the front of a fit of several looks (a candidate, never a look)


@dataclass(frozen=True)
class Perceived:
    """One look's outcome: the estimate, its world pose and the view it came from."""

    concept: str
    params: dict[str, Any]  # instantiate's values (estimated floats, defaults for the rest)
    pose: np.ndarray  # world <- concept
    joints: dict[str, float]
    residual: float
    confidence: float
    source: str  # "fit" or "learned+fit"
    view: View
    points: int  # object pixels the estimate used
    seconds: float
    estimate: Estimate | None = field(default=None, compare=False, repr=False)
    part_points: int = -1  # the handle's pixels in view (-1: the concept has no handle)
    sight: Sight | None = field(default=None, compare=False, repr=False)

    def instance(self, concept: Concept) -> Instance:
        """The agent's model of the object: the estimated instance at its world pose."""
        inst = concept.instantiate(params=dict(self.params), pose=self.pose)
        return with_joints_clipped(inst, self.joints)

    def summary(self) -> dict[str, Any]:
        """A JSON-able account (for records and reports)."""
        return {
            "view": [round(self.view.azimuth, 2), round(self.view.elevation, 2)],
            "points": self.points,
            "handle_points": self.part_points,
            "residual_mm": round(1000 * self.residual, 2),
            "confidence": round(self.confidence, 3),
            "source": self.source,
            "seconds": round(self.seconds, 3),
        }


def with_joints_clipped(inst: Instance, joints: Mapping[str, float]) -> Instance:
    """``inst`` with ``joints`` clipped into its ranges: a fit ends a hair past a stop
    (-1e-11 rad), which ``with_joints`` rightly refuses."""
    limits = inst.joint_limits()
    clipped = {
        name: min(max(float(q), limits[name][0]), limits[name][1]) if name in limits else q
        for name, q in joints.items()
    }
    return inst.with_joints(clipped) if clipped else inst


def camera_for(view: View, target: np.ndarray, radius: float) -> Camera:
    """A camera at ``view`` looking at ``target`` from ``FRAMING`` bounding radii."""
    w, h = IMAGE
    x, y, z = (float(v) for v in target)
    dist = FRAMING * max(radius, 0.05)
    return Camera(view.azimuth, view.elevation, dist, (x, y, z), width=w, height=h)


def render_from(
    scene: Scene, model: mujoco.MjModel, data: mujoco.MjData, camera: Camera
) -> tuple[Frame, np.ndarray]:
    """The scene's ``view`` camera moved to ``camera`` (pose and field of view), rendered, and
    put back: a look from anywhere without recompiling the world. Also the geom seen at each
    pixel (-1: none), which names the parts (``handle__bar``: part ``handle``)."""
    cid = model.camera("view").id
    saved = (model.cam_pos[cid].copy(), model.cam_quat[cid].copy(), float(model.cam_fovy[cid]))
    pose = camera.pose()
    model.cam_pos[cid] = pose[:3, 3]
    model.cam_quat[cid] = _quat(pose[:3, :3])
    model.cam_fovy[cid] = camera.fovy
    try:
        _place_cameras(model, data)
        frame = replace(scene, camera=camera).render(model, data)
        geoms = _geom_ids(model, data, camera)
    finally:
        model.cam_pos[cid], model.cam_quat[cid], model.cam_fovy[cid] = saved
        _place_cameras(model, data)
    return frame, geoms


def _geom_ids(model: mujoco.MjModel, data: mujoco.MjData, camera: Camera) -> np.ndarray:
    """Per pixel the MuJoCo geom seen from camera ``view`` (-1: none): the parts' labels."""
    import mujoco

    with mujoco.Renderer(model, camera.height, camera.width) as renderer:
        renderer.enable_segmentation_rendering()
        renderer.update_scene(data, camera="view")
        seg = renderer.render().copy()
    ids, types = seg[..., 0], seg[..., 1]
    return np.where(types == int(mujoco.mjtObj.mjOBJ_GEOM), ids, -1).astype(np.int32)


def _place_cameras(model: mujoco.MjModel, data: mujoco.MjData) -> None:
    """The cameras' world poses from the model (rendering reads them from ``data``)."""
    import mujoco

    mujoco.mj_kinematics(model, data)
    mujoco.mj_camlight(model, data)


def object_shot(
    frame: Frame,
    scene: Scene,
    model: mujoco.MjModel,
    index: int,
    geoms: np.ndarray | None = None,
) -> DepthRender:
    """The frame as perception's ``DepthRender``: OpenCV camera pose and intrinsics, per pixel
    the index of the object ``index``'s link it sees (-1: anything else) and, given ``geoms``
    (``render_from``), of its shape (``handle.bar``: what the segmenter's part queries use)."""
    links = tuple(scene.instances[index].links)
    position = {name: k for k, name in enumerate(links)}
    labels = np.full(frame.segmentation.shape, -1, dtype=np.int16)
    for body in np.unique(frame.segmentation):
        owner = scene.link_of(model, int(body)) if body > 0 else None
        if owner is not None and owner[0] == index and owner[1] in position:
            labels[frame.segmentation == body] = position[owner[1]]
    shapes: list[str] = []
    shape_labels = None
    if geoms is not None:
        shape_labels = np.full(geoms.shape, -1, dtype=np.int16)
        prefix = scene.prefixes[index]
        spelled = _shape_names(scene.instances[index])
        for g in np.unique(geoms[labels >= 0]):
            name = model.geom(int(g)).name
            if not name.startswith(prefix):
                continue
            shape = _shape_of(name[len(prefix) :].removesuffix("__collision"), spelled)
            if shape not in shapes:
                shapes.append(shape)
            shape_labels[(geoms == g) & (labels >= 0)] = shapes.index(shape)
    camera_pose = frame.camera.pose() @ CV
    return DepthRender(frame.depth, labels, links, camera_pose, intrinsics(frame), shape_labels,
                       tuple(shapes))  # fmt: skip


def _shape_names(inst: Instance) -> dict[str, str]:
    """The concept's outermost shape names by their spelling in the exported model's geom
    names (``handle@bar.bar`` is ``handle_bar__bar`` there): labels must name the concept's
    own shapes and parts, which the fit resolves."""
    from grace_dsl.export.common import xml_name
    from grace_dsl.runtime.shapes import ShapeTree

    return {xml_name(n): n for n in ShapeTree(inst).outermost()}


def _shape_of(stem: str, spelled: Mapping[str, str]) -> str:
    """The concept shape a geom stands for: its name, or the longest one it extends (a shape
    exported in convex pieces: ``tray__back`` is a piece of ``tray``)."""
    if stem in spelled:
        return spelled[stem]
    owners = [k for k in spelled if stem.startswith(k + "__") or stem.startswith(k + "_")]
    return spelled[max(owners, key=len)] if owners else stem.replace("__", ".")


def intrinsics(frame: Frame) -> Intrinsics:
    """Perception's pinhole model of a sim frame (pixel centres at u + 0.5)."""
    cam = frame.camera
    f = cam.focal()
    return Intrinsics(f, f, cam.width / 2 - 0.5, cam.height / 2 - 0.5, cam.width, cam.height)


def object_cloud(
    shot: DepthRender,
    rgb: np.ndarray,
    concept: str,
    seed: int,
    segmenter: Segmenter | None = None,
    noise: float = NOISE,
    part: str = "",
) -> tuple[np.ndarray, np.ndarray | None]:
    """The object's camera-frame cloud (OpenCV axes: the segmenter's masks for the concept's
    name joined) from the depth with the sensor's noise (seeded), and that of its ``part``
    (None when not asked for or not in view)."""
    cloud = labelled_cloud(shot, rgb, concept, seed, segmenter, noise)
    if not part:
        return cloud.points, None
    on_part = cloud.on(part)
    return cloud.points, cloud.points[on_part] if on_part.any() else None


@dataclass(frozen=True)
class LabelledCloud:
    """The object's camera-frame points and, per point, the name of the region it lies on:
    its part where the segmenter tells one (``handle``), else its link (``drawer``)."""

    points: np.ndarray  # (N, 3)
    labels: np.ndarray  # (N,) str
    #: (N,) str, the largest region holding each point: its link (a part lies in its link)
    owners: np.ndarray | None = None

    def __len__(self) -> int:
        return len(self.points)

    def on(self, part: str) -> np.ndarray:
        """Points on ``part``: labelled with it, a variant of it or one of its shapes
        (``handle@bar`` and ``handle.left_post`` are the ``handle``'s)."""
        names, which = np.unique(np.asarray(self.labels, str), return_inverse=True)
        hit = np.array([_part_of(str(n)) == part for n in names], bool)
        return hit[which.reshape(-1)] if len(names) else np.zeros(0, bool)

    def count(self, label: str) -> int:
        return int(np.count_nonzero(self.on(label)))

    def owned_by(self, link: str) -> np.ndarray:
        """Points on ``link`` (its parts' included)."""
        owners = self.labels if self.owners is None else self.owners
        return np.asarray(owners == link, bool)


def _part_of(label: str) -> str:
    """The part a label names (``handle`` of ``handle@bar`` and of ``handle.bar``)."""
    return label.split(".")[0].split("@")[0]


def labelled_cloud(
    shot: DepthRender,
    rgb: np.ndarray,
    concept: str,
    seed: int,
    segmenter: Segmenter | None = None,
    noise: float = NOISE,
) -> LabelledCloud:
    """The object's cloud with a label per point, from the segmenter's masks for the concept's
    name: a pixel in several masks takes the smallest one's name (a handle inside its drawer's
    link is the handle) as its label and the largest one's (the drawer) as its owner, so any
    segmenter that names parts and links gives both. With the renderer's ground truth (no
    ``segmenter`` given) a pixel on a named shape is labelled with that shape
    (``handle.left_post``): finer labels pin a bar's ends, where a part label lets a longer bar
    cover the same points. The depth gets the sensor's noise (seeded); pixels with no return
    are dropped."""
    seg = segmenter if segmenter is not None else GroundTruthSegmenter(shot, concept)
    depth = DepthNoise(sigma=noise).apply(shot.depth, np.random.default_rng(seed))
    masks = seg.segment(rgb, depth, concept)
    if segmenter is None and shot.shape_labels is not None:  # the renderer's shapes
        masks = {**masks, **{n: shot.shape_labels == k for k, n in enumerate(shot.shapes)}}
    names = sorted(masks, key=lambda k: (-int(np.count_nonzero(masks[k])), k))
    region = np.full(depth.shape, -1, dtype=np.int32)
    owner = np.full(depth.shape, -1, dtype=np.int32)
    for k, name in enumerate(names):  # largest first: smaller regions overwrite
        region[np.asarray(masks[name], bool)] = k
    for k in reversed(range(len(names))):  # largest last: it owns what it holds
        owner[np.asarray(masks[names[k]], bool)] = k
    inside = region >= 0
    points = back_project(depth, shot.intrinsics, inside)
    table = np.array(names if names else [""], dtype=object)
    kept = inside & (depth > 0)
    return LabelledCloud(points, table[region[kept]].astype(str), table[owner[kept]].astype(str))


def estimate_cloud(
    concept: Concept,
    points: np.ndarray | LabelledCloud,
    camera_pose: np.ndarray,
    seed: int = 0,
    fixed: Mapping[str, Any] | None = None,
) -> tuple[Estimate, np.ndarray]:
    """``eac.estimate`` on a camera-frame cloud, started from the shipped network (its
    parameters and pose, from the whole cloud) where the concept has weights, with the ``fixed``
    (non-float) parameters given; the estimate and the concept's world pose.

    A ``LabelledCloud`` goes whole with its labels (each point then measured against the
    shapes of its own part, link or shape; the fit thins it keeping every label's share, so
    the handle's pixels count, and reads the outline's free space from all of them)."""
    from grace_dsl.perception.estimate import estimate
    from grace_dsl.perception.views import join_params
    from grace_dsl.perception.weights import shipped_path

    cloud = points if isinstance(points, LabelledCloud) else None
    whole = cloud.points if cloud is not None else np.asarray(points, float)
    init: dict[str, Any] = dict(fixed or {})
    hint = None
    if shipped_path(concept.name).is_file() and len(whole) >= 1:
        from grace_dsl.perception.learned import estimate_learned

        learned = estimate_learned(concept, whole)
        init, hint = join_params(concept, learned.params, init), learned.pose
    labels = None if cloud is None else list(cloud.labels)
    est = estimate(concept, whole, init=init or None, pose_hint=hint, seed=seed, labels=labels)
    if hint is not None:
        est = replace(est, source="learned+fit")
    return est, np.asarray(camera_pose, float) @ est.pose


def fixed_params(concept: Concept, given: Mapping[str, Any] | None = None) -> dict[str, Any]:
    """The parameters perception does not estimate (integers, choices, flags): from ``given``
    (the structure the scene or the draw states) where it has them, else the defaults."""
    defaults = concept.instantiate().params
    given = given or {}
    return {
        s.name: given.get(s.name, defaults[s.name])
        for s in concept.params
        if s.kind not in ("num", "vec")
    }


def perceive(
    concept: Concept,
    points: np.ndarray | LabelledCloud,
    camera_pose: np.ndarray,
    view: View,
    seed: int = 0,
    min_confidence: float = MIN_CONFIDENCE,
    fixed: Mapping[str, Any] | None = None,
    part_points: int = -1,
) -> Perceived:
    """Estimate ``concept`` from a camera-frame cloud (``fixed``: its non-float parameters,
    ``fixed_params``; ``part_points``: the handle's pixels in view, -1 unknown, reported);
    ``EstimateRefused`` when the cloud is unusable (too few points, bad values) or the
    estimate's confidence is below ``min_confidence``."""
    from grace_dsl.perception.views import join_params

    fixed = fixed_params(concept) if fixed is None else dict(fixed)
    try:
        est, pose = estimate_cloud(concept, points, camera_pose, seed, fixed)
    except (PerceptionError, ParameterError) as exc:  # a bad cloud; a fit outside the concept
        first = str(exc).splitlines()[0] if str(exc) else type(exc).__name__
        raise EstimateRefused(f"{concept.name} from view {_view(view)}: {first}") from exc
    got = Perceived(
        concept.name,
        join_params(concept, est.params, fixed),
        pose,
        dict(est.joints),
        float(est.residual),
        float(est.confidence),
        est.source,
        view,
        len(points),
        float(est.seconds),
        est,
        part_points,
    )
    if not got.confidence >= min_confidence:
        raise EstimateRefused(
            f"{concept.name} from view {_view(view)}: confidence {got.confidence:.2f} is below "
            f"{min_confidence:.2f} (residual {1000 * got.residual:.1f} mm on {len(points)} "
            "points); take another view",
            got,
        )
    return got


def look(
    scene: Scene,
    model: mujoco.MjModel,
    data: mujoco.MjData,
    index: int,
    concept: Concept,
    view: View,
    target: np.ndarray,
    radius: float,
    seed: int = 0,
    segmenter: Segmenter | None = None,
    min_confidence: float = MIN_CONFIDENCE,
    fixed: Mapping[str, Any] | None = None,
    hold: str = "",
) -> Perceived:
    """Render the world from ``view`` about ``target``, segment object ``index`` with a label
    per point (``labelled_cloud``) and estimate its concept (``perceive``); also refused when
    the estimated front (the concept's +z, the side a robot approaches, where its handle is)
    faces away from the camera: the view did not show what the agent would grasp, or when
    fewer than ``MIN_PART_POINTS`` pixels are seen of the concept's handle (if it has one) or
    of link ``hold`` (the link the task moves: a door's leaf is hidden from behind). A refusal
    carries what was seen (``Sight``: where those pixels were, the estimated front), from which
    ``next_view`` chooses where to look next."""
    camera = camera_for(view, target, radius)
    frame, geoms = render_from(scene, model, data, camera)
    shot = object_shot(frame, scene, model, index, geoms)
    cloud = labelled_cloud(shot, frame.rgb, concept.name, seed, segmenter)
    wanted = any(p.split("@")[0] == PART for p in _parts(concept))
    seen = cloud.count(PART) if wanted else -1
    held = cloud.owned_by(hold) if hold else np.zeros(len(cloud), bool)
    centre = (float(target[0]), float(target[1]), float(target[2]))
    handle_at = _centroid(cloud, cloud.on(PART), shot.camera_pose) if seen > 0 else None
    world = Look(_to_world(cloud.points, shot.camera_pose), shot.camera_pose, cloud.labels)
    n_held = int(held.sum()) if hold else -1
    sight = Sight(view, centre, handle_at, handle=seen, cloud=world, held=n_held)
    for name, n in ((PART, seen), (hold, int(held.sum()) if hold else -1)):
        if 0 <= n < MIN_PART_POINTS:  # the back or the side: what it would hold is not in view
            why = (
                f"{concept.name} from view {_view(view)}: {n} pixels of its {name} are in view "
                f"(at least {MIN_PART_POINTS} needed); take another view"
            )
            try:  # never acted on: only where its front points, to choose the next view
                guess = perceive(concept, cloud, shot.camera_pose, view, seed, 0.0, fixed, seen)
            except EstimateRefused:
                raise EstimateRefused(why, sight=sight) from None
            raise EstimateRefused(why, _seen(guess, sight))
    try:
        got = perceive(concept, cloud, shot.camera_pose, view, seed, min_confidence, fixed, seen)
    except EstimateRefused as exc:
        if exc.perceived is None:
            raise EstimateRefused(str(exc), sight=sight) from exc
        raise EstimateRefused(str(exc), _seen(exc.perceived, sight)) from exc
    got = _seen(got, sight)
    eye = camera.pose()[:3, 3]
    toward = (eye - got.pose[:3, 3]) / max(float(np.linalg.norm(eye - got.pose[:3, 3])), 1e-9)
    if float(got.pose[:3, 2] @ toward) <= 0.0:
        raise EstimateRefused(
            f"{concept.name} from view {_view(view)}: the estimated front faces away from the "
            "camera, so the side to grasp was not in view; take another view",
            got,
        )
    return got


def _to_world(points: np.ndarray, camera_pose: np.ndarray) -> np.ndarray:
    pose = np.asarray(camera_pose, float)
    return np.asarray(points, float) @ pose[:3, :3].T + pose[:3, 3]


#: degrees past square a fused fit's front may face its nearest camera (several cameras round
#: the object: a front seen edge-on from two sides was in view, a front turned away from all is not)
GRAZING = 10.0


def fuse(
    concept: Concept,
    sights: Sequence[Sight],
    guesses: Sequence[Perceived],
    seed: int = 0,
    min_confidence: float = MIN_CONFIDENCE,
    fixed: Mapping[str, Any] | None = None,
    fit: Any = None,
) -> Perceived:
    """One estimate from every look taken (``eac.estimate(..., looks=)``: the clouds in the
    world frame, free space and outline per camera), started from the single looks' fits
    (``guesses``, the most confident first). When that fit is not confident enough, the
    looks are fitted again from each of the two most confident single fits alone
    (``FUSE_RETRIES``): single fits that disagree can start the joint fit in neither basin,
    and the run from one of them is screened by the fused cost like the first (the most
    confident run is kept). Refused (``EstimateRefused``) like one look: too few of the
    handle's or the moved link's pixels in all the looks together (the fit is still run then,
    never acted on: its front says where to look next), a confidence below
    ``min_confidence``, or a front that faces away from every camera (``front_in_view``).
    ``fit(clouds, starts)``: the fit to run (default ``eac.estimate``)."""
    from grace_dsl.perception.views import join_params

    clouds = [s.cloud for s in sights if s.cloud is not None]
    views = " + ".join(_view(s.view) for s in sights)
    if len(clouds) < 2:
        raise EstimateRefused(f"{concept.name}: {len(clouds)} look(s) to fuse (2 needed)")
    short = ""
    for what, counts in (
        ("handle", [s.handle for s in sights]),
        ("moved link", [s.held for s in sights]),
    ):
        if min(counts) >= 0 and sum(counts) < MIN_PART_POINTS and not short:
            short = (
                f"{concept.name} from views {views} fused: {sum(counts)} pixels of its {what} "
                f"in view (at least {MIN_PART_POINTS} needed); take another view"
            )
    fixed = fixed_params(concept) if fixed is None else dict(fixed)
    run = fit if fit is not None else _fused_fit(concept, fixed, seed)
    ranked = sorted((g for g in guesses if g.estimate is not None), key=lambda g: -g.confidence)
    starts = [replace(g.estimate, pose=g.pose) for g in ranked if g.estimate is not None]
    tries = [starts, *([s] for s in starts[:FUSE_RETRIES] if len(starts) > 1)]
    best: Estimate | None = None
    failure = ""
    for k, some in enumerate(tries):
        if k > 0 and (short or (best is not None and best.confidence >= min_confidence)):
            break  # confident (or only a guess for the next view): no retry
        try:
            est = run(clouds, some)
        except (PerceptionError, ParameterError) as exc:
            failure = failure or (str(exc).splitlines()[0] if str(exc) else type(exc).__name__)
            continue
        if best is None or (est.confidence, -est.residual) > (best.confidence, -best.residual):
            best = est
    if best is None:
        raise EstimateRefused(f"{concept.name} from views {views} fused: {failure}")
    est = best
    got = Perceived(
        concept.name,
        join_params(concept, est.params, fixed),
        np.asarray(est.pose, float),
        dict(est.joints),
        float(est.residual),
        float(est.confidence),
        "fused",
        sights[-1].view,
        sum(len(c.points) for c in clouds),
        float(est.seconds),
        est,
        sum(max(s.handle, 0) for s in sights) if sights[0].handle >= 0 else -1,
    )
    handle = sum(max(s.handle, 0) for s in sights) if sights[0].handle >= 0 else -1
    got = _seen(got, replace(sights[-1], handle=handle, handle_at=None, fused=True))
    confident = got.confidence >= min_confidence
    cameras = [c.camera for c in clouds if isinstance(c.camera, np.ndarray)]
    if short:
        raise EstimateRefused(short, got)
    if not confident:
        raise EstimateRefused(
            f"{concept.name} from views {views} fused: confidence {got.confidence:.2f} is below "
            f"{min_confidence:.2f} (residual {1000 * got.residual:.1f} mm); take another view",
            got,
        )
    if not front_in_view(got.pose, cameras):
        raise EstimateRefused(
            f"{concept.name} from views {views} fused: the estimated front faces away from "
            "every camera; take another view",
            got,
        )
    return got


def scene_of(inst: Instance) -> tuple[Scene, mujoco.MjModel, mujoco.MjData]:
    """``inst`` as a MuJoCo scene at its own pose, without the floor (an episode's world has
    none and its object's centre is at the origin), its joints at their values."""
    import mujoco

    scene = Scene.from_instances([inst], up="keep")
    spec = scene.spec()
    spec.delete(spec.geom("floor"))
    model = spec.compile()
    data = mujoco.MjData(model)
    for exported, prefix in zip(scene.models, scene.prefixes, strict=True):
        for j in exported.joints:
            if j.kind != "fixed":
                data.qpos[model.jnt_qposadr[model.joint(prefix + j.name).id]] = j.value
    mujoco.mj_forward(model, data)
    return scene, model, data


#: single fits a refused fused fit is run again from, one at a time (the most confident first)
FUSE_RETRIES = 2


def _fused_fit(concept: Concept, fixed: Mapping[str, Any], seed: int) -> Any:
    """``eac.estimate`` of the looks from the given starts (world-frame single fits)."""
    from grace_dsl.perception.estimate import estimate

    def run(clouds: Sequence[Look], starts: Sequence[Estimate]) -> Estimate:
        return estimate(concept, looks=list(clouds), init=dict(fixed), starts=starts, seed=seed)

    return run


def front_in_view(
    pose: np.ndarray, cameras: Sequence[np.ndarray], grazing: float = GRAZING
) -> bool:
    """Whether the estimated front (the concept's +z at ``pose``) was in view of one of
    ``cameras`` (4x4 world poses): for one camera it must face it; for several (the looks
    round the object, fused) it may be up to ``grazing`` degrees past square to the nearest
    (two side views each see a front edge-on: a laptop's, seen from azimuths 96 and 276, was
    refused at confidence 0.96 although every look had shown it)."""
    z = np.asarray(pose, float)[:3, 2]
    origin = np.asarray(pose, float)[:3, 3]
    limit = 0.0 if len(cameras) <= 1 else -math.sin(math.radians(grazing))
    for cam in cameras:
        d = np.asarray(cam, float)[:3, 3] - origin
        if float(z @ d) / max(float(np.linalg.norm(d)), 1e-9) > limit:
            return True
    return False


#: radians: the grid a frameless leaf's joint is chosen on (``frameless_joint``)
FRAMELESS_STEP = math.radians(0.5)


def frameless_joint(
    concept: Concept, got: Perceived, joint: str, upright: np.ndarray
) -> Perceived | None:
    """A frameless leaf's joint from the object's known base orientation, or None when the
    concept has geometry off the joint's moving link (then the view shows the joint itself).

    Why: a door leaf with no frame looks the same turned about its hinge as with its hinge
    turned; the fit's joint and the base's rotation trade off freely, and an estimate 110 deg
    off came back at confidence 1.00. The leaf's place in the world is what the view fixes, so
    it is kept, and of the (base pose, joint) pairs that put the leaf there the one whose base
    rotation is nearest ``upright`` (3x3: how the scene or the protocol stands the object) is
    taken."""
    from grace_dsl.runtime.shapes import ShapeTree

    child = str(concept.joints[joint]["child"])
    inst = got.instance(concept)
    tree = ShapeTree(inst)
    if any(tree.shapes[n]["link"] != child for n in tree.outermost()):
        return None
    leaf = inst.link_pose(child)
    lo, hi = inst.joint_limits()[joint]
    base = concept.instantiate(params=dict(got.params))

    def off(q: float) -> tuple[float, float, np.ndarray]:
        rel = base.with_joints({**got.joints, joint: q}).link_pose(child)
        pose = leaf @ np.linalg.inv(rel)
        cos = (float(np.trace(pose[:3, :3].T @ np.asarray(upright, float))) - 1) / 2
        return math.acos(max(-1.0, min(1.0, cos))), q, pose

    coarse = 10 * FRAMELESS_STEP  # then the grid's step within one coarse step of the best
    best = min((off(float(q)) for q in np.arange(lo, hi + 1e-9, coarse)), key=lambda b: b[0])
    near = np.arange(best[1] - coarse, best[1] + coarse + 1e-9, FRAMELESS_STEP)
    fine = [off(float(q)) for q in near if lo <= q <= hi]
    best = min([best, *fine], key=lambda b: b[0])
    return replace(got, pose=best[2], joints={**got.joints, joint: best[1]})


def _seen(got: Perceived, sight: Sight) -> Perceived:
    """``got`` with its sight, the estimated front and the fit's confidence included."""
    z = got.pose[:3, 2]
    front = (float(z[0]), float(z[1]), float(z[2]))
    return replace(got, sight=replace(sight, front=front, confidence=float(got.confidence)))


def _centroid(
    cloud: LabelledCloud, on: np.ndarray, camera_pose: np.ndarray
) -> tuple[float, float, float] | None:
    """The world centroid of the points ``on`` (None when there are none)."""
    if not on.any():
        return None
    c = np.asarray(camera_pose, float) @ np.append(cloud.points[on].mean(axis=0), 1.0)
    return (float(c[0]), float(c[1]), float(c[2]))


def next_view(first: View, sights: Sequence[Sight], hint: Sight | None = None) -> View:
    """Where to look after the refused ``sights`` (a robot walking round the object). The
    candidate directions: the front of ``hint`` (a refused fit of all the looks together)
    when it is at least ``MIN_CONFIDENCE`` sure (refused for the side it showed, not for its
    fit); toward the face where the handle's pixels were seen, newest sight first (the
    horizontal direction from the aimed-at centre to their centroid: a handle sits on the
    front); toward the face the estimated fronts point at, the most confident fit first and
    only fits at least ``FRONT_TRUST`` sure (a fit at confidence ~0 points anywhere;
    ``_front``: turned round when it faced a camera that saw none of the handle); then, while
    no handle was seen, from the opposite side of the last view (from behind nothing of the
    front shows). The first candidate at least ``SAME_VIEW`` degrees from every view taken
    wins; if none is, the first is turned by 45, then 90 degrees either way.

    The elevation stays in the protocol's band (``ELEVATIONS``): ``LOW_ELEVATION`` while no
    look has shown any of a handle (an oven's open door hides its handle from above), else the
    first look's, at most ``HIGH_ELEVATION`` (a front seen from high above is foreshortened).
    A function of the sights: the same sights give the same view."""
    taken = [s.view.azimuth for s in sights]
    hidden = bool(sights) and all(s.handle == 0 for s in sights)
    low, high = ELEVATIONS
    elevation = LOW_ELEVATION if hidden else min(max(first.elevation, low), HIGH_ELEVATION, high)
    trusted = hint is not None and hint.front is not None and hint.confidence >= MIN_CONFIDENCE
    candidates: list[float] = []
    ahead = _azimuth(hint.front) if trusted and hint is not None and hint.front else None
    if ahead is not None:
        candidates.append(ahead)
    for s in reversed(sights):
        toward = _toward(s.centre, s.handle_at)
        if toward is not None:
            candidates.append(toward)
    fitted = [s for s in reversed(sights) if s.front is not None and s.confidence >= FRONT_TRUST]
    for s in sorted(fitted, key=lambda s: -s.confidence):  # stable: newest first among ties
        front = _front(s)
        if front is not None:
            candidates.append(front)
    if taken and not any(s.handle_at is not None for s in sights):
        candidates.append((taken[-1] + 180.0) % 360.0)
    if not candidates:
        return View(first.azimuth, min(max(first.elevation, low), high))
    for c in candidates:
        if all(_apart(c, t) >= SAME_VIEW for t in taken):
            return View(round(c, 6), elevation)
    for turn in (45.0, -45.0, 90.0, -90.0, 180.0):
        cand = (candidates[0] + turn) % 360.0
        if all(_apart(cand, t) >= SAME_VIEW for t in taken):
            return View(round(cand, 6), elevation)
    return View((candidates[0] + 180.0) % 360.0, elevation)


def _front(sight: Sight) -> float | None:
    """The azimuth the sight's estimated front points at. A front facing the camera although
    none of the handle was in view is a flipped estimate (a box's back read as its front): the
    true front is then the other way."""
    azimuth = None if sight.front is None else _azimuth(sight.front)
    if azimuth is not None and sight.handle == 0 and _apart(azimuth, sight.view.azimuth) < 90:
        return (azimuth + 180.0) % 360.0
    return azimuth


def _toward(
    centre: tuple[float, float, float], at: tuple[float, float, float] | None
) -> float | None:
    """The azimuth (degrees) from ``centre`` to ``at`` in the horizontal plane (None when
    ``at`` is None or right above ``centre``)."""
    if at is None:
        return None
    d = np.asarray(at, float) - np.asarray(centre, float)
    return _azimuth(tuple(d)) if math.hypot(d[0], d[1]) > 1e-3 else None


def _azimuth(direction: Sequence[float]) -> float | None:
    """The azimuth (degrees, world xy from +x toward +y: the camera's convention) of a
    direction, None when it is (nearly) vertical."""
    x, y = float(direction[0]), float(direction[1])
    if math.hypot(x, y) < 0.2 * max(1e-9, float(np.linalg.norm(direction))):
        return None
    return math.degrees(math.atan2(y, x)) % 360.0


def _apart(a: float, b: float) -> float:
    return abs((a - b + 180.0) % 360.0 - 180.0)


def look_around(
    views: Sequence[View] | View,
    see: Any,
    looks: int = 0,
    fused: Any = None,
) -> tuple[Perceived | None, list[dict[str, Any]]]:
    """Try ``see(view)`` until one is not refused: the first accepted estimate (None if every
    look was refused) and an account of every look. Given a list, its views in turn; given one
    view, that first and then up to ``looks`` in all, each next one chosen by ``next_view``
    from what the refused looks showed. Given ``fused(sights, guesses)`` (``fuse`` bound to a
    concept), from the second look on every look taken is fitted at once too; that estimate
    is taken when accepted, else the look's own when accepted, else the next view."""
    fixed = list(views) if not isinstance(views, View) else None
    first = views if isinstance(views, View) else fixed[0] if fixed else View(0.0, 45.0)
    limit = len(fixed) if fixed is not None else max(1, looks)
    account: list[dict[str, Any]] = []
    sights: list[Sight] = []
    guesses: list[Perceived] = []
    hint: Sight | None = None  # the last refused fused fit's sight: where its front points
    for k in range(limit):
        view = (
            fixed[k] if fixed is not None else first if k == 0 else next_view(first, sights, hint)
        )
        alone: Perceived | None = None
        try:
            alone = see(view)
        except EstimateRefused as exc:
            entry = exc.perceived.summary() if exc.perceived is not None else {"view": _pair(view)}
            account.append({**entry, "refused": str(exc)})
            sights.append(exc.sight if exc.sight is not None else Sight(view, (0.0, 0.0, 0.0)))
            if exc.perceived is not None:
                guesses.append(exc.perceived)
        if alone is not None:
            account.append(alone.summary())
            if fused is None or k == 0 or alone.sight is None:
                return alone, account
            sights.append(alone.sight)
            guesses.append(alone)
        if fused is not None and k >= 1:
            try:
                together = fused(sights, guesses)
            except EstimateRefused as exc:
                entry = exc.perceived.summary() if exc.perceived is not None else {}
                account.append({**entry, "fused": len(sights), "refused": str(exc)})
                if exc.perceived is not None and exc.perceived.sight is not None:
                    hint = replace(exc.perceived.sight, fused=True)
            else:
                account.append({**together.summary(), "fused": len(sights)})
                return together, account
        if alone is not None:
            return alone, account
    return None, account


def _parts(concept: Concept) -> set[str]:
    """The concept's part names (the prefixes of its dotted parameter names: ``handle``)."""
    return {s.name.split(".")[0] for s in concept.params if "." in s.name}


def _view(view: View) -> str:
    return f"(azimuth {view.azimuth:.0f}, elevation {view.elevation:.0f} deg)"


def _pair(view: View) -> list[float]:
    return [round(view.azimuth, 2), round(view.elevation, 2)]


def _quat(rot: np.ndarray) -> np.ndarray:
    """(w, x, y, z) of a rotation matrix: MuJoCo's order."""
    import mujoco

    out = np.zeros(4)
    mujoco.mju_mat2Quat(out, np.ascontiguousarray(rot, float).reshape(9))
    return out


def _radius(inst: Instance) -> tuple[np.ndarray, float]:
    """Centre and half-diagonal of the instance's world bounding box (camera framing)."""
    lo, hi = inst.mesh(resolution=16).bounds
    lo, hi = np.asarray(lo, float), np.asarray(hi, float)
    return (lo + hi) / 2, float(np.linalg.norm(hi - lo) / 2)


def frame_of(inst: Instance) -> tuple[np.ndarray, float]:
    """Where to aim and how far to stand: the object's bounding box centre and radius."""
    centre, radius = _radius(inst)
    return centre, radius if math.isfinite(radius) else 0.5


class Estimator:
    """The ``estimated`` mode's ``ParamSource`` for ``agent.execute.Executor``: each call looks
    at the object anew (its state may have changed) from the next view of ``views`` (degrees),
    and returns the estimated parameters; ``perceived(name)`` is the last accepted look, whose
    pose and joints ``instance`` turns into the agent's model of the object.

    The views cycle: a retry after a failed attempt looks from the next one (a re-estimate from
    a new view, bounded by the executor's attempts). The camera is aimed at the object's
    position from the scene file (where the agent was told the object is), framed by the object's
    size; only the pixels go into the estimate.

    Looks are fused (``fuse``, as the benchmark's estimated mode): the looks at an object since
    its last accepted estimate were refused, so nothing acted on it and it stands as they saw
    it; from the second such look on, all of them are fitted at once, and that estimate is
    taken when accepted (else the new look's own when accepted). An accepted estimate starts
    the object's looks afresh (the agent may now move it). ``fuse_looks=False``: each look
    alone."""

    def __init__(
        self,
        views: Sequence[tuple[float, float]] = ((0.0, 40.0), (35.0, 50.0), (-35.0, 35.0)),
        min_confidence: float = MIN_CONFIDENCE,
        seed: int = 0,
        segmenter: Segmenter | None = None,
        fuse_looks: bool = True,
    ):
        if not views:
            raise PerceptionError("an Estimator needs at least one view (azimuth, elevation)")
        self.views = [View(float(a), float(e)) for a, e in views]
        self.min_confidence = min_confidence
        self.seed = seed
        self.segmenter = segmenter
        self.fuse_looks = fuse_looks
        self.looks: dict[str, int] = {}
        self.last: dict[str, Perceived] = {}
        self.account: list[dict[str, Any]] = []  # every look (and fused fit), in order
        self._last_look: dict[str, dict[str, Any]] = {}
        # per object, the looks since its last accepted estimate: (what it saw, its fit or None)
        self._pending: dict[str, list[tuple[Sight, Perceived | None]]] = {}

    def next_view(self, obj: SceneObject) -> View:
        """The object's next view, relative to the way its front faces (its scene yaw)."""
        k = self.looks.get(obj.name, 0)
        self.looks[obj.name] = k + 1
        base = self.views[k % len(self.views)]
        return View((base.azimuth + math.degrees(obj.yaw)) % 360.0, base.elevation)

    def perceive(self, obj: SceneObject, world: MultiWorld, concept: Concept) -> Perceived:
        """One look at ``obj`` in ``world``, fused with the refused looks before it (raises
        ``EstimateRefused`` when neither is accepted)."""
        index = world.names.index(obj.name)
        centre, radius = frame_of(world.scene.instances[index])  # where the scene says it is
        view = self.next_view(obj)
        seed = self.seed + 7919 * self.looks[obj.name]
        fixed = fixed_params(concept, obj.params)
        pending = self._pending.setdefault(obj.name, [])
        try:
            got = look(world.scene, world.world.model, world.world.data, index, concept, view,
                       centre, radius, seed, self.segmenter, self.min_confidence,
                       fixed)  # fmt: skip
        except EstimateRefused as exc:
            entry = exc.perceived.summary() if exc.perceived is not None else {"view": _pair(view)}
            self.account.append({"object": obj.name, **entry, "refused": str(exc)})
            self._last_look[obj.name] = self.account[-1]
            if exc.sight is not None:
                pending.append((exc.sight, exc.perceived))
            together = self._fused(obj.name, concept, fixed)
            if together is None:
                raise
            return together
        self.account.append({"object": obj.name, **got.summary()})
        self._last_look[obj.name] = self.account[-1]
        if pending and got.sight is not None:
            pending.append((got.sight, got))
            together = self._fused(obj.name, concept, fixed)
            if together is not None:
                return together
        self._pending[obj.name] = []
        self.last[obj.name] = got
        return got

    def _fused(self, name: str, concept: Concept, fixed: Mapping[str, Any]) -> Perceived | None:
        """The object's pending looks fitted together (``fuse``), accepted, or None (fewer
        than two looks, fusing off, or the fused estimate refused: recorded either way)."""
        pending = self._pending.get(name, [])
        if not self.fuse_looks or len(pending) < 2:
            return None
        sights = [s for s, _ in pending]
        guesses = [g for _, g in pending if g is not None]
        try:
            got = fuse(concept, sights, guesses, self.seed, self.min_confidence, fixed)
        except EstimateRefused as exc:
            entry = exc.perceived.summary() if exc.perceived is not None else {}
            self.account.append(
                {"object": name, **entry, "fused": len(sights), "refused": str(exc)}
            )
            return None
        self.account.append({"object": name, **got.summary(), "fused": len(sights)})
        self._last_look[name] = self.account[-1]
        self._pending[name] = []
        self.last[name] = got
        return got

    def last_look(self, name: str) -> dict[str, Any]:
        """The account of the last look at object ``name`` ({} before the first)."""
        return dict(self._last_look.get(name, {}))

    def params(self, obj: SceneObject, world: MultiWorld) -> dict[str, Any]:
        concept = world.scene.instances[world.names.index(obj.name)].concept
        return dict(self.perceive(obj, world, concept).params)

    def instance(self, obj: SceneObject, world: MultiWorld) -> Instance:
        """A new look at ``obj``, as the agent's posed model of it (estimated joints)."""
        concept = world.scene.instances[world.names.index(obj.name)].concept
        return self.perceive(obj, world, concept).instance(concept)

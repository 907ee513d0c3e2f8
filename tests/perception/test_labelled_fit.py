"""The part-labelled fit: label resolution, typed errors, recovery, flips caught."""

from __future__ import annotations

import math

import numpy as np
import pytest

from grace_dsl.perception.estimate import confidence, estimate
from grace_dsl.perception.fit import (
    CAUCHY,
    FREE_WEIGHT,
    LABEL_MARGIN,
    Fitter,
    _State,
    free_space,
    rotation_exp,
)
from grace_dsl.perception.labels import (
    LabelError,
    check_labels,
    covered,
    label_masks,
    labelled_points,
    subsample,
    valid_labels,
)
from grace_dsl.perception.model import parts_model, sdf_model
from grace_dsl.perception.outline import outline_rays
from grace_dsl.perception.views import generate_labelled_views, join_params
from grace_dsl.runtime.shapes import ShapeTree

SHAPES = ("carcass", "panel", "box", "handle.bar", "handle.left_post", "handle.right_post")
LINKS = ("base", "drawer", "drawer", "drawer", "drawer", "drawer")
HELDOUT = 1_000_003


def test_a_label_covers_its_link_part_or_shape() -> None:
    assert covered("drawer", SHAPES, LINKS).tolist() == [False, True, True, True, True, True]
    assert covered("handle", SHAPES, LINKS).tolist() == [False] * 3 + [True] * 3
    assert covered("handle.bar", SHAPES, LINKS).tolist() == [False] * 3 + [True, False, False]
    assert covered("", SHAPES, LINKS).all()  # unlabelled: every shape
    variant = ("panel", "handle@bar.bar", "handle@bar.left_post")
    assert covered("handle", variant, ("leaf",) * 3).tolist() == [False, True, True]
    assert "handle@bar" in valid_labels(variant, ("leaf",) * 3)


def test_an_unknown_label_names_the_valid_ones() -> None:
    with pytest.raises(LabelError, match=r"'knob'.*valid: base, drawer, handle, carcass"):
        label_masks(np.array(["panel", "knob"]), SHAPES, LINKS, "CabinetDrawer")


def test_labels_must_be_one_name_per_point() -> None:
    with pytest.raises(LabelError, match="3 entries for 4 points"):
        check_labels(["panel"] * 3, 4)
    with pytest.raises(LabelError, match="str part names"):
        check_labels(["panel", 3, "box", "box"], 4)
    with pytest.raises(LabelError, match="sequence of part names"):
        check_labels("panel", 5)


def test_estimate_refuses_bad_labels_with_typed_errors(lib) -> None:
    pts = np.random.default_rng(0).normal(size=(200, 3)) * 0.1 + [0, 0, 1.5]
    with pytest.raises(LabelError, match="199 entries for 200 points"):
        estimate(lib["CabinetDrawer"], pts, labels=["panel"] * 199)
    with pytest.raises(LabelError, match="'lid' names no part of CabinetDrawer"):
        estimate(lib["CabinetDrawer"], pts, labels=["lid"] * 200)


def test_the_subsample_keeps_every_part() -> None:
    labels = np.array(["carcass"] * 9000 + ["panel"] * 900 + ["handle.bar"] * 12)
    keep = subsample(labels, 384, np.random.default_rng(0))
    assert len(keep) <= 384 and len(set(keep)) == len(keep)
    assert (labels[keep] == "handle.bar").sum() == 12  # all of the few
    assert (labels[keep] == "carcass").sum() > (labels[keep] == "panel").sum()


def test_labelled_points_joins_part_clouds() -> None:
    pts, labels = labelled_points({"panel": np.zeros((5, 3)), "handle": np.ones((2, 3))})
    assert pts.shape == (7, 3) and labels == ["panel"] * 5 + ["handle"] * 2
    with pytest.raises(LabelError):
        labelled_points({})


@pytest.mark.slow
def test_the_per_shape_distances_are_the_union_apart(lib) -> None:
    concept = lib["CabinetDrawer"]
    inst = concept.instantiate(joints={"slide": 0.1})
    shapes = tuple(ShapeTree(inst).shapes)
    parts, union = parts_model(concept, shapes), sdf_model(concept, shapes)
    assert parts.shapes == tuple(ShapeTree(inst).outermost())
    pts = np.random.default_rng(1).normal(size=(200, 3)) * 0.3
    theta = inst.p[list(parts.float_index)]
    d = np.asarray(parts.value.batch(theta, inst.p, inst.q, np.zeros(6), pts)).reshape(200, -1)
    u = np.asarray(union.value.batch(theta, inst.p, inst.q, np.zeros(6), pts)).reshape(-1)
    np.testing.assert_allclose(d.min(axis=1), u, atol=1e-12)


def _errors(concept, view, est) -> tuple[dict[str, float], float, float]:
    err = {k: 1000 * abs(est.params[k] - view.params[k]) for k in view.params}
    rel = est.pose[:3, :3].T @ view.pose[:3, :3]
    deg = math.degrees(math.acos(float(np.clip((np.trace(rel) - 1) / 2, -1, 1))))
    return err, 1000 * float(np.linalg.norm(est.pose[:3, 3] - view.pose[:3, 3])), deg


@pytest.mark.slow
def test_the_labelled_fit_recovers_a_drawer_the_unlabelled_one_misses(lib) -> None:
    """Noise-free, every pixel of the first held-out view (its handle: 1 % of the pixels)."""
    concept = lib["CabinetDrawer"]
    view, labels = generate_labelled_views(concept, 1, HELDOUT, noise=0.0, every_pixel=True)[0]
    pts = view.points.astype(float)
    err, mm, deg = _errors(concept, view, estimate(concept, pts, labels=labels))
    assert err["handle.length"] < 3 and err["handle_y"] < 3, err
    assert mm < 3 and deg < 2, (mm, deg)
    plain, _, _ = _errors(concept, view, estimate(concept, pts))
    assert max(plain["handle.length"], plain["handle_y"]) > 3, plain


@pytest.mark.slow
def test_the_labelled_fit_puts_a_cabinets_handle_on_its_points(lib) -> None:
    """HingedCabinet, noise-free: the handle's size and place in space (its points on its own
    shapes), the rotation and the hinge side. Not asserted: ``handle_y`` and the origin, which
    inherit the height error when the cabinet's bottom edge is a few pixels (docs)."""
    concept = lib["HingedCabinet"]
    view, labels = generate_labelled_views(concept, 2, HELDOUT, noise=0.0, every_pixel=True)[1]
    pts = view.points.astype(float)
    est = estimate(concept, pts, labels=labels)
    err, mm, deg = _errors(concept, view, est)
    assert err["handle.length"] < 3 and err["handle.radius"] < 3, err
    assert err["handle_y"] < 5 and mm < 5 and deg < 2, (err, mm, deg)
    assert est.discrete["hinge_side"] == view.fixed["hinge_side"]
    assert est.confidence > 0.5


def _flipped(view) -> np.ndarray:
    flip = np.eye(4)
    flip[:3, :3] = rotation_exp(np.array([0.0, math.pi, 0.0]))
    return view.pose @ flip


@pytest.mark.slow
def test_a_fit_turned_180_degrees_is_corrected_or_not_trusted(lib) -> None:
    concept = lib["CabinetDrawer"]
    view, labels = generate_labelled_views(concept, 1, HELDOUT, noise=0.002, every_pixel=True)[0]
    pts = view.points.astype(float)
    est = estimate(concept, pts, labels=labels, pose_hint=_flipped(view))
    _, mm, deg = _errors(concept, view, est)
    assert (deg < 3 and mm < 10) or est.confidence < 0.5, (mm, deg, est.confidence)
    # held at the flipped pose (no iterations), the front's points are off the front
    params = join_params(concept, view.params, view.fixed)
    some = np.random.default_rng(0).choice(len(pts), 2000, replace=False)
    names = np.array(labels)[some]
    fitter = Fitter(concept, params, view.joints, labels=names)
    held = fitter.run(pts[some], _flipped(view), np.zeros(3), iterations=0)
    assert held.part_inliers < 0.5
    assert confidence(held.residual, held.inliers, 2000, held.part_inliers) < 0.5
    right = fitter.run(pts[some], view.pose, np.zeros(3), iterations=0)
    assert confidence(right.residual, right.inliers, 2000, right.part_inliers) > 0.8


@pytest.mark.slow
def test_the_outline_pulls_a_too_tall_and_too_deep_start_back(lib) -> None:
    """HingedCabinet, noise-free: a start 52 mm too tall and 60 mm too deep whose extra lies
    where no point is (below the bottom edge, behind the back) fits every point; only the rays
    outside the silhouette see it. Free space alone leaves it, the outline term shrinks it."""
    concept = lib["HingedCabinet"]
    view, names = generate_labelled_views(concept, 1, HELDOUT, noise=0.0, every_pixel=True)[0]
    pts, labels = view.points.astype(float), np.array(names)
    truth = join_params(concept, view.params, view.fixed)
    rng = np.random.default_rng(0)
    free = free_space(pts, np.zeros(3), 0, LABEL_MARGIN)
    free = free[rng.choice(len(free), 768, replace=False)]
    outline = outline_rays(pts, np.zeros(3), 0)
    assert outline is not None
    keep = subsample(labels, 384, rng)
    extra = np.array([0.0, 0.052, 0.06])  # within the typical range of this view's size
    start = truth | {"size": tuple(np.asarray(truth["size"]) + extra)}
    shift = np.eye(4)
    shift[1, 3], shift[2, 3] = -extra[1] / 2, -extra[2] / 2  # the seen top and front in place
    errors = {}
    for key, rays in (("free", None), ("outline", outline)):
        fitter = Fitter(concept, start, view.joints, CAUCHY, labels[keep], strict=False)
        fitted = fitter.run(pts[keep], view.pose @ shift, np.zeros(3), 40, free, rays)
        errors[key] = np.abs(np.asarray(fitted.params["size"]) - truth["size"]) * 1000
    assert errors["free"][1] > 45 and errors["free"][2] > 50, errors  # nothing pulls
    assert errors["outline"][1] < 40 and errors["outline"][2] < 30, errors


def test_the_outline_rays_lie_just_outside_the_silhouette() -> None:
    """A 0.4 m square 2 m away on a 2 mm grid: every ray passes outside it, within 8 spacings
    of its edge, on each of its four sides; a cloud too small has no outline."""
    g = np.arange(-0.2, 0.2 + 1e-9, 0.002)
    x, y = np.meshgrid(g, g)
    square = np.stack([x.ravel(), y.ravel(), np.full(x.size, 2.0)], axis=1)
    outline = outline_rays(square, np.zeros(3), seed=0)
    assert outline is not None and len(outline.dirs) == 256
    at = outline.dirs * (2.0 / outline.dirs[:, 2:])  # where each ray crosses the square's plane
    edge = np.abs(at[:, :2]).max(axis=1)
    assert np.all(edge > 0.2 + 1.5 * 0.002) and np.all(edge < 0.2 + 9 * 0.002), edge
    sides = np.sign(at[:, :2])[np.arange(len(at)), np.abs(at[:, :2]).argmax(axis=1)]
    assert len(set(zip(np.abs(at[:, :2]).argmax(axis=1), sides))) == 4
    assert outline.near < 2.0 < outline.far
    assert outline_rays(square[:10], np.zeros(3)) is None


@pytest.mark.slow
def test_the_jacobian_at_the_weighted_rows_only_gives_the_full_systems_residuals(lib) -> None:
    """``Fitter.residuals`` evaluates the compiled gradient at the data points and at the
    free-space points the surface reaches only; the residuals and Jacobian are those of every
    row evaluated (the other free-space rows weigh nothing)."""
    concept = lib["CabinetDrawer"]
    view, names = generate_labelled_views(concept, 1, HELDOUT, noise=0.002, every_pixel=True)[0]
    pts, labels = view.points.astype(float), np.array(names)
    keep = subsample(labels, 256, np.random.default_rng(0))
    truth = join_params(concept, view.params, view.fixed)
    taller = truth | {"front": tuple(np.asarray(truth["front"]) + [0.03, 0.05, 0.0])}
    fitter = Fitter(concept, taller, view.joints, CAUCHY, labels[keep], strict=False)
    frame = np.linalg.inv(view.pose)
    y = pts[keep] @ frame[:3, :3].T + frame[:3, 3]
    free = free_space(pts, np.zeros(3), 0, LABEL_MARGIN) @ frame[:3, :3].T + frame[:3, 3]
    st = _State(fitter.theta0, fitter.q0, np.eye(4))
    r, jac, _ = fitter.residuals(st, y, free, True)
    r0, _, _ = fitter.residuals(st, y, free, False)
    np.testing.assert_allclose(r, r0, atol=1e-12)
    d, g = fitter.distances(st, np.concatenate([y, free]), True, len(y))
    assert g is not None and jac is not None
    reached = np.concatenate([np.ones(len(y), bool), d[len(y) :] < 0])
    assert 0 < reached[len(y) :].sum() < len(free)  # some free rows weigh, not all
    n = len(y)
    wd = 1.0 / np.sqrt(1.0 + (d[:n] / CAUCHY) ** 2)
    wf = FREE_WEIGHT * (d[n:] < 0)
    full = np.concatenate([wd[:, None] * g[:n], wf[:, None] * g[n:]]) / math.sqrt(n)
    np.testing.assert_allclose(jac[: len(full)], full, atol=1e-12)
    assert not jac[len(y) : len(full)][~reached[len(y) :]].any()


@pytest.mark.slow
def test_the_spread_tells_what_the_view_shows_from_what_it_cannot(lib) -> None:
    """A drawer's ``travel`` moves no surface: its reported spread is about its range; the
    front's width and the handle's length, which the points show, are sure to millimetres."""
    concept = lib["CabinetDrawer"]
    view, labels = generate_labelled_views(concept, 1, HELDOUT, noise=0.002, every_pixel=True)[0]
    est = estimate(concept, view.points.astype(float), labels=labels)
    assert set(est.spread) == set(est.params)
    travel = next(s for s in concept.params if s.name == "travel")
    assert est.spread["travel"] > 0.3 * (travel.hi - travel.lo), est.spread
    assert est.spread["front[0]"] < 0.003 and est.spread["handle.length"] < 0.003, est.spread

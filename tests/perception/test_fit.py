"""The analytic fit: the compiled distance, recovery of known parameters, degenerate input."""

from __future__ import annotations

import math

import numpy as np
import pytest

import grace_dsl as eac
from grace_dsl.perception.camera import DepthNoise
from grace_dsl.perception.errors import PointCloudError
from grace_dsl.perception.estimate import estimate
from grace_dsl.perception.fit import rotation_exp
from grace_dsl.perception.model import sdf_model
from grace_dsl.perception.types import Estimate
from grace_dsl.perception.views import ViewConfig, draw_view, float_params
from grace_dsl.runtime.shapes import ShapeTree


@pytest.mark.slow
def test_compiled_distance_and_gradient_match_the_instance(lib) -> None:
    concept = lib["CabinetDrawer"]
    inst = concept.instantiate(joints={"slide": 0.12})
    model = sdf_model(concept, tuple(ShapeTree(inst).shapes))
    pts = np.random.default_rng(0).normal(size=(300, 3)) * 0.25
    theta = inst.p[list(model.float_index)]
    d = np.asarray(model.value.batch(theta, inst.p, inst.q, np.zeros(6), pts)).reshape(-1)
    np.testing.assert_allclose(d, inst.sdf(pts), atol=1e-12)
    # d/d(depth) by finite differences, away from kinks
    _, g = model.gradient.batch(theta, inst.p, inst.q, np.zeros(6), pts)
    k = float_params(concept).index("depth")
    bumped = theta.copy()
    bumped[k] += 1e-6
    d2 = np.asarray(model.value.batch(bumped, inst.p, inst.q, np.zeros(6), pts)).reshape(-1)
    fd = (d2 - d) / 1e-6
    smooth = np.abs(fd - np.asarray(g).reshape(300, -1)[:, k]) < 1e-3
    assert smooth.mean() > 0.95


def _near(concept: eac.Concept, view, rng: np.random.Generator) -> Estimate:  # type: ignore[no-untyped-def]
    params = {}
    for s in concept.params:
        if s.kind == "num":
            span = s.hi - s.lo
            params[s.name] = float(
                np.clip(view.params[s.name] + 0.05 * span * rng.normal(), s.lo, s.hi)
            )
    pose = view.pose.copy()
    pose[:3, :3] = pose[:3, :3] @ rotation_exp(np.radians([1.0, -1.0, 1.0]))
    pose[:3, 3] += [0.003, -0.003, 0.003]
    return Estimate(concept.name, params, pose, dict(view.joints), 0.0, 1.0, 0.0, "near")


@pytest.mark.slow
@pytest.mark.parametrize("name", ["StraightHandle", "RoundKnob"])
def test_fit_recovers_known_parameters_from_noise_free_points(lib, name: str) -> None:
    concept = lib[name]
    view = draw_view(concept, 11, ViewConfig(points=1024, noise=DepthNoise(sigma=0.0)))
    est = estimate(concept, view.points, init=_near(concept, view, np.random.default_rng(2)))
    for k, truth in view.params.items():
        assert abs(est.params[k] - truth) < 0.002, (k, est.params[k], truth)
    assert np.linalg.norm(est.pose[:3, 3] - view.pose[:3, 3]) < 0.003
    assert est.residual < 0.001 and est.confidence > 0.8 and est.source == "learned+fit"


def test_degenerate_clouds_are_typed_errors(lib) -> None:
    c = lib["StraightHandle"]
    with pytest.raises(PointCloudError, match="empty"):
        estimate(c, np.zeros((0, 3)))
    with pytest.raises(PointCloudError, match="shape"):
        estimate(c, np.zeros((100, 2)))
    with pytest.raises(PointCloudError, match="NaN"):
        estimate(c, np.full((100, 3), math.nan))
    with pytest.raises(PointCloudError, match="too few"):
        estimate(c, np.ones((5, 3)))
    with pytest.raises(PointCloudError):
        estimate(c, "not points")
    assert eac.estimate is estimate


@pytest.mark.slow
def test_a_cloud_of_the_wrong_object_gets_a_low_confidence(lib) -> None:
    """A microwave's cloud fitted as a straight handle: an estimate, but one no caller trusts."""
    view = draw_view(lib["Microwave"], 5, ViewConfig(points=512))
    est = estimate(lib["StraightHandle"], view.points)
    assert est.confidence < 0.3 and est.residual > 0.003
    sphere = np.random.default_rng(0).normal(size=(400, 3))
    sphere = 0.1 * sphere / np.linalg.norm(sphere, axis=1, keepdims=True) + [0, 0, 0.8]
    assert estimate(lib["CabinetDrawer"], sphere).confidence < 0.3

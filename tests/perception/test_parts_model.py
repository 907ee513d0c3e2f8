"""The labelled fit's model evaluated in two steps (placements once, then per point) against
the one-graph union it replaced for the fit."""

from __future__ import annotations

import numpy as np
import pytest

from grace_dsl.perception.model import parts_model, sdf_model
from grace_dsl.runtime.shapes import ShapeTree


@pytest.mark.slow
def test_the_split_distances_and_gradients_equal_the_one_graph_union(lib) -> None:
    concept = lib["CabinetDrawer"]
    inst = concept.instantiate(joints={"slide": 0.1})
    shapes = tuple(ShapeTree(inst).shapes)
    parts, union = parts_model(concept, shapes), sdf_model(concept, shapes)
    rng = np.random.default_rng(3)
    pts = rng.normal(size=(600, 3)) * 0.3
    theta = inst.p[list(parts.float_index)]
    w = np.zeros(6)
    d = parts.distances(theta, inst.p, inst.q, w, pts)
    u = np.asarray(union.value.batch(theta, inst.p, inst.q, w, pts)).reshape(-1)
    np.testing.assert_allclose(d.min(axis=1), u, atol=1e-9)
    # the union's gradient is its nearest shape's: the split gives it from that shape alone
    k = d.argmin(axis=1)
    dk, gk = parts.gradients(theta, inst.p, inst.q, w, pts, k)
    ud, ug = union.gradient.batch(theta, inst.p, inst.q, w, pts)
    np.testing.assert_allclose(dk, np.asarray(ud).reshape(-1), atol=1e-9)
    np.testing.assert_allclose(gk, np.asarray(ug).reshape(len(pts), -1), atol=1e-9)
    assert np.abs(gk[:, : len(theta)]).max() > 0.5  # the parameters' columns are not empty
    # every shape's gradient at once (the model's older API) agrees column by column
    da, ga = parts.gradient.batch(theta, inst.p, inst.q, w, pts)
    np.testing.assert_allclose(da, d, atol=1e-12)
    np.testing.assert_allclose(ga[np.arange(len(pts)), k], gk, atol=1e-12)

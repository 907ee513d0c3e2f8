"""Synthetic views and shards: determinism, ground truth that matches the points, the CLI."""

from __future__ import annotations

import numpy as np
import pytest

from grace_dsl.perception import views
from grace_dsl.perception.camera import DepthNoise
from grace_dsl.perception.dataset import generate_dataset
from grace_dsl.perception.errors import PerceptionError
from grace_dsl.perception.shards import read_shard
from grace_dsl.perception.types import SHARD_SCHEMA
from grace_dsl.perception.views import (
    ViewConfig,
    float_params,
    generate_views,
    join_params,
    random_instance,
    render_view,
)


def _arrays(views):  # type: ignore[no-untyped-def]
    return [(v.points, v.pose, v.camera_pose, sorted(v.params.items()), v.seed) for v in views]


def test_same_seed_gives_identical_views_and_another_seed_does_not(lib) -> None:
    a = generate_views(lib["CurveHandle"], 2, seed=7, points=256)
    b = generate_views(lib["CurveHandle"], 2, seed=7, points=256)
    for x, y in zip(_arrays(a), _arrays(b)):
        np.testing.assert_array_equal(x[0], y[0])
        np.testing.assert_array_equal(x[1], y[1])
        assert x[3] == y[3] and x[4] == y[4]
    c = generate_views(lib["CurveHandle"], 1, seed=8, points=256)
    assert not np.array_equal(a[0].points, c[0].points)
    # a view is replayable alone from its index
    d = generate_views(lib["CurveHandle"], 1, seed=7, points=256, start=1)
    np.testing.assert_array_equal(d[0].points, a[1].points)


def test_noise_free_points_lie_on_the_instance_at_the_ground_truth_pose(lib) -> None:
    concept = lib["CabinetDrawer"]
    config = ViewConfig(points=512, noise=DepthNoise(sigma=0.0))
    rv = render_view(concept, 3, config)
    s = rv.sample
    assert s.points.shape == (512, 3) and s.points.dtype == np.float32
    assert tuple(s.params) == float_params(concept)
    inst = concept.instantiate(params=join_params(concept, s.params, s.fixed), joints=s.joints)
    concept_pts = (np.linalg.inv(s.pose) @ np.c_[s.points, np.ones(512)].T).T[:, :3]
    assert np.abs(inst.sdf(concept_pts)).max() < 1e-3  # float32 points at ~1 m: 1e-4 rounding
    np.testing.assert_allclose(s.pose @ s.camera_pose, np.eye(4), atol=1e-12)
    assert np.all(s.points[:, 2] > 0)  # in front of the camera


@pytest.mark.slow
def test_dataset_shards_are_the_same_with_one_or_two_workers(lib, tmp_path) -> None:
    config = ViewConfig(points=128)
    one = generate_dataset(
        lib, ["StraightHandle"], 5, tmp_path / "a", seed=3, config=config, shard_size=3
    )
    two = generate_dataset(
        lib, ["StraightHandle"], 5, tmp_path / "b", seed=3, config=config, workers=2, shard_size=3
    )
    assert [p.name for p in one] == ["StraightHandle-0000.npz", "StraightHandle-0001.npz"]
    for p, q in zip(one, two):
        a, b = read_shard(p), read_shard(q)
        assert a.meta == b.meta and a.meta["schema"] == SHARD_SCHEMA
        for k in a.arrays:
            np.testing.assert_array_equal(a.arrays[k], b.arrays[k])
    shard = read_shard(one[0])
    assert shard.arrays["points"].shape == (3, 128, 3)
    assert shard.arrays["params"].shape == (3, len(shard.param_names))
    views = shard.views()
    assert views[0].params == dict(zip(shard.param_names, shard.arrays["params"][0].tolist()))


def test_bad_inputs_are_typed_errors(lib, tmp_path) -> None:
    with pytest.raises(PerceptionError, match="points"):
        generate_views(lib["CurveHandle"], 1, points=0)
    with pytest.raises(PerceptionError, match="no link"):
        render_view(lib["CurveHandle"], 0, ViewConfig(part="door"))
    bad = tmp_path / "x.npz"
    bad.write_bytes(b"not a zip")
    with pytest.raises(PerceptionError, match="not a view shard"):
        read_shard(bad)


@pytest.mark.slow
def test_a_concept_with_a_variant_handle_gets_valid_draws(lib, monkeypatch) -> None:  # type: ignore[no-untyped-def]
    """DoorLeaf's handle is one of five variants, each with its own requirements: 13 % of
    uniform draws of its 19 parameters meet them all (38 of 300), so 40 uniform tries failed
    now and then (`grace data gen DoorLeaf` stopped in its first 160 views). After the uniform
    tries the draw is repaired as `eacc verify` repairs it; here one uniform try only."""
    monkeypatch.setattr(views, "MAX_TRIES", 1)
    concept = lib["DoorLeaf"]
    kinds = set()
    for seed in range(6):
        inst = random_instance(concept, np.random.default_rng(seed))
        assert set(inst.params) == {s.name for s in concept.params}
        kinds.add(inst.params["handle_kind"])
    assert len(kinds) > 1  # the repair keeps the drawn variants, not one easy one

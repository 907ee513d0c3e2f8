"""The learned estimator: the network's pieces, a tiny end-to-end training run, the weights
file's checks and the typed errors for bad clouds.

The clouds here are stand-ins made in the test (surface samples of random draws, turned and
moved as a camera would see them); the shipped weights' test uses real views."""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest

torch = pytest.importorskip("torch")

from grace_dsl.perception.errors import ModelWeightsError, PointCloudError  # noqa: E402
from grace_dsl.perception.learned import LearnedEstimator, join_floats  # noqa: E402
from grace_dsl.perception.point_transformer import (  # noqa: E402
    ModelConfig,
    PointTransformer,
    farthest_point_sample,
    group,
)
from grace_dsl.perception.train import (  # noqa: E402
    TrainConfig,
    ViewArrays,
    train,
    with_model,
)
from grace_dsl.perception.weights import read_weights, write_weights  # noqa: E402
from grace_dsl.runtime.verify import draw_params  # noqa: E402

TINY = with_model(
    TrainConfig(epochs=3, batch=8, points=128, seed=3),
    groups=16, group_size=8, dim=16, blocks=1, k=4, trunk=16, head=8,
)  # fmt: skip


def _rotation_y(a: float) -> np.ndarray:
    c, s = np.cos(a), np.sin(a)
    return np.array([[c, 0, s], [0, 1, 0], [-s, 0, c]])


def stand_in(concept, n: int, seed: int = 0, points: int = 256) -> ViewArrays:  # type: ignore[no-untyped-def]
    """Surface samples of ``n`` random instances, each turned about y and pushed 0.8 m ahead."""
    rng = np.random.default_rng(seed)
    names = [s.name for s in concept.params if s.kind == "num"]
    clouds, params, poses = [], [], []
    while len(clouds) < n:
        values = draw_params(concept, rng)
        try:
            inst = concept.instantiate(params=values)
        except Exception:  # a draw that breaks a requirement: draw again
            continue
        pose = np.eye(4)
        pose[:3, :3] = _rotation_y(rng.uniform(-0.6, 0.6))
        pose[:3, 3] = [rng.uniform(-0.1, 0.1), rng.uniform(-0.1, 0.1), 0.8]
        pts = inst.sample_surface(points, seed=int(rng.integers(1 << 30)))
        clouds.append(pts @ pose[:3, :3].T + pose[:3, 3])
        params.append([values[k] for k in names])
        poses.append(pose)
    return ViewArrays(concept.name, tuple(names), np.array(clouds, np.float32),
                      np.array(params), np.array(poses))  # fmt: skip


def test_farthest_point_sample_spreads_and_repeats_nothing() -> None:
    xyz = torch.rand(2, 200, 3)
    idx = farthest_point_sample(xyz, 20)
    assert idx.shape == (2, 20)
    for row in idx:
        assert len(set(row.tolist())) == 20
    picked = xyz[0, idx[0]]
    gaps = torch.cdist(picked, picked) + torch.eye(20) * 9
    # far-first: its points are farther apart than the first 20 points of the cloud
    first = xyz[0, :20]
    assert gaps.min() > (torch.cdist(first, first) + torch.eye(20) * 9).min()


def test_network_shapes_and_rotation_head() -> None:
    cfg = ModelConfig(n_params=5, groups=16, group_size=8, dim=16, blocks=1, k=4)
    model = PointTransformer(cfg)
    params, pose = model(torch.randn(3, 128, 3))
    assert params.shape == (3, 5) and pose is not None and pose.shape == (3, 9)
    centres, local, neighbours = group(torch.randn(2, 128, 3), cfg)
    assert centres.shape == (2, 16, 3) and local.shape == (2, 16, 8, 3)
    assert neighbours.shape == (2, 16, 4)


@pytest.fixture(scope="module")
def tiny_weights(lib, tmp_path_factory: pytest.TempPathFactory) -> Path:  # type: ignore[no-untyped-def]
    """A tiny network trained once for the tests that only need some weights file."""
    data = stand_in(lib["StraightHandle"], 8, seed=4, points=128)
    return train(data, tmp_path_factory.mktemp("w") / "w.npz", TINY).path


@pytest.mark.slow
def test_tiny_training_run_writes_loadable_deterministic_weights(lib, tmp_path: Path) -> None:
    concept = lib["StraightHandle"]
    data = stand_in(concept, 24, seed=1)
    a = train(data, tmp_path / "a.npz", TINY)
    b = train(data, tmp_path / "b.npz", TINY)
    assert len(a.history) == 3 and not (tmp_path / "a.npz.ckpt").exists()
    wa, wb = read_weights(a.path, "StraightHandle"), read_weights(b.path, "StraightHandle")
    assert json.dumps(wa.trained["val_mae"]) == json.dumps(wb.trained["val_mae"])
    for k in wa.tensors:
        np.testing.assert_array_equal(wa.tensors[k], wb.tensors[k])
    est = LearnedEstimator.load(concept, a.path).predict(data.points[0])
    assert est.source == "learned" and set(est.params) == set(data.param_names)
    lo, hi = wa.lo, wa.hi
    for name, low, high in zip(wa.param_names, lo, hi, strict=True):
        assert low - 0.2 * (high - low) <= est.params[name] <= high + 0.2 * (high - low)
    assert np.allclose(est.pose[:3, :3] @ est.pose[:3, :3].T, np.eye(3), atol=1e-6)
    assert np.isfinite(est.residual) or est.confidence == 0.0
    assert 0.0 <= est.confidence <= 1.0


@pytest.mark.slow
def test_training_resumes_from_its_checkpoint(lib, tmp_path: Path) -> None:
    data = stand_in(lib["StraightHandle"], 16, seed=2, points=128)
    whole = train(data, tmp_path / "whole.npz", TINY)
    # stop after one epoch by keeping the checkpoint of a one-epoch run, then resume to three
    from dataclasses import replace

    out = tmp_path / "part.npz"
    train(data, out, replace(TINY, epochs=1))
    assert not out.with_name("part.npz.ckpt").exists()  # a finished run removes its checkpoint
    calls: list[int] = []

    def stop_after_first(epoch: int, epochs: int, row: dict[str, float]) -> None:
        calls.append(epoch)
        if epoch == 1:
            raise KeyboardInterrupt

    with pytest.raises(KeyboardInterrupt):
        train(data, out, TINY, progress=stop_after_first)
    assert out.with_name("part.npz.ckpt").exists()
    resumed = train(data, out, TINY)
    assert [r["train"] for r in resumed.history] == [r["train"] for r in whole.history]


def test_weights_refuse_other_concepts_edits_and_pickles(
    lib, tmp_path: Path, tiny_weights: Path
) -> None:  # type: ignore[no-untyped-def]
    path = tiny_weights
    with pytest.raises(ModelWeightsError, match="not RoundKnob"):
        read_weights(path, "RoundKnob")
    with pytest.raises(ModelWeightsError, match="not RoundKnob"):
        LearnedEstimator.load(lib["RoundKnob"], path)
    wf = read_weights(path)
    key = sorted(wf.tensors)[0]
    bad = {**wf.tensors, key: wf.tensors[key] + 1.0}
    with np.load(path, allow_pickle=False) as z:
        meta = str(z["meta"])
    tampered = tmp_path / "tampered.npz"
    np.savez_compressed(tampered, meta=np.array(meta),
                        **{"t/" + k: v.astype(np.float16) for k, v in bad.items()})  # fmt: skip
    with pytest.raises(ModelWeightsError, match="checksum"):
        read_weights(tampered)
    pickled = tmp_path / "pickled.npz"
    np.savez(pickled, meta=np.array([{"schema": "x"}], dtype=object))
    with pytest.raises(ModelWeightsError):
        read_weights(pickled)
    torch.save({"a": 1}, tmp_path / "torch.npz")
    with pytest.raises(ModelWeightsError):
        read_weights(tmp_path / "torch.npz")
    other = write_weights(tmp_path / "v.npz", wf)
    with np.load(other) as z:
        m = json.loads(str(z["meta"]))
    m["version"] = 99
    stored = {"t/" + k: v.astype(np.float16) for k, v in wf.tensors.items()}
    np.savez_compressed(tmp_path / "v99.npz", meta=np.array(json.dumps(m)), **stored)
    with pytest.raises(ModelWeightsError, match="version 99"):
        read_weights(tmp_path / "v99.npz")
    with pytest.raises(ModelWeightsError, match="no weights file"):
        read_weights(tmp_path / "missing.npz")


@pytest.mark.parametrize(
    ("cloud", "match"),
    [
        (np.zeros((0, 3)), "at least"),
        (np.zeros((100, 2)), r"\(N, 3\)"),
        (np.full((100, 3), np.nan), "NaN"),
        (np.zeros((5, 3)), "at least"),
    ],
)
def test_bad_clouds_raise_point_cloud_error(lib, tiny_weights, cloud, match) -> None:  # type: ignore[no-untyped-def]
    est = LearnedEstimator.load(lib["StraightHandle"], tiny_weights)
    with pytest.raises(PointCloudError, match=match):
        est.predict(cloud)


def test_join_floats_rebuilds_vectors(lib) -> None:
    drawer = lib["CabinetDrawer"]
    out = join_floats(drawer, {"front[0]": 0.5, "front[1]": 0.2, "front[2]": 0.02, "depth": 0.4})
    assert out == {"front": (0.5, 0.2, 0.02), "depth": 0.4}

"""The perception commands: ``grace data gen`` and ``grace estimate`` (each loads the library)."""

from __future__ import annotations

import json

import numpy as np
import pytest

from grace_dsl.cli.grace import main as grace_main
from grace_dsl.perception.shards import read_shard
from grace_dsl.perception.views import ViewConfig, draw_view


@pytest.mark.slow
def test_grace_data_gen_writes_shards_and_refuses_an_unknown_concept(tmp_path, capsys) -> None:
    out = tmp_path / "d"
    args = ["data", "gen", "RoundKnob", "-n", "2", "--points", "64", "--workers", "1", "-o"]
    assert grace_main([*args, str(out)]) == 0
    assert read_shard(out / "RoundKnob-0000.npz").arrays["points"].shape == (2, 64, 3)
    assert grace_main(["data", "gen", "NoSuchThing", "-n", "1", "-o", str(out)]) == 1
    assert "NoSuchThing" in capsys.readouterr().err


@pytest.mark.slow
def test_grace_estimate_prints_the_fit_and_draws_it(lib, tmp_path, capsys) -> None:
    view = draw_view(lib["CurveHandle"], 4, ViewConfig(points=256))
    cloud = tmp_path / "knob.npy"
    np.save(cloud, view.points.astype(float))
    png = tmp_path / "fit.png"
    assert (
        grace_main(
            ["estimate", "CurveHandle", str(cloud), "--png", str(png), "--size", "96", "--json"]
        )
        == 0
    )
    out = json.loads(capsys.readouterr().out)
    assert set(out["params"]) == set(view.params) and 0 <= out["confidence"] <= 1
    assert png.read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"
    bad = tmp_path / "bad.npy"
    np.save(bad, np.zeros((10, 2)))
    assert grace_main(["estimate", "CurveHandle", str(bad)]) == 1
    assert "shape" in capsys.readouterr().err

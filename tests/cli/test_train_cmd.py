"""``grace train``: trains from shards and writes checked weights; bad input is one line, exit 1."""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest

pytest.importorskip("torch")

from grace_dsl.cli.grace import main  # noqa: E402
from grace_dsl.perception.shards import write_shard  # noqa: E402
from grace_dsl.perception.types import ViewSample  # noqa: E402
from grace_dsl.perception.views import ViewConfig  # noqa: E402
from grace_dsl.perception.weights import read_weights  # noqa: E402
from tests.perception.test_learned import stand_in  # noqa: E402


def test_train_without_data_is_one_line_and_exit_1(tmp_path: Path, capsys) -> None:  # type: ignore[no-untyped-def]
    code = main(["train", "StraightHandle", "--data", str(tmp_path), "-o", str(tmp_path / "w.npz")])
    assert code == 1
    err = capsys.readouterr().err
    assert "no grace-eac.views/1 shards of StraightHandle" in err
    assert len(err.strip().splitlines()) == 1


@pytest.mark.slow
def test_train_from_shards_writes_weights_with_its_command(lib, tmp_path: Path, capsys) -> None:  # type: ignore[no-untyped-def]
    data = stand_in(lib["StraightHandle"], 8, seed=7, points=96)
    views = [
        ViewSample("StraightHandle", data.points[i],
                   dict(zip(data.param_names, map(float, data.params[i]), strict=True)),
                   data.poses[i], np.eye(4), {}, i)
        for i in range(8)
    ]  # fmt: skip
    write_shard(tmp_path / "data" / "StraightHandle-0000.npz", views, [], ViewConfig(points=96))
    out = tmp_path / "w.npz"
    args = ["train", "StraightHandle", "--data", str(tmp_path / "data"), "--epochs", "1",
            "--points", "64", "--seed", "3", "-o", str(out), "--json"]  # fmt: skip
    assert main(args) == 0
    result = json.loads(capsys.readouterr().out)
    assert set(result["val_mae"]) == {"length", "radius", "standoff"}
    wf = read_weights(out, "StraightHandle")
    assert wf.points == 64 and wf.trained["views"] == 8
    assert "--seed 3" in wf.trained["command"]

"""Dataset shards: compressed ``.npz`` files of views of one concept (``SHARD_SCHEMA``).

Besides the arrays the schema lists, a shard holds ``fixed`` (M,) str: each view's non-float
parameters as JSON (a cabinet's hinge side differs from view to view, so the meta's ``fixed``
keeps only the values every view shares). Arrays only, no pickles: a shard from elsewhere is
read with ``allow_pickle=False``.
"""

from __future__ import annotations

import json
from collections.abc import Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

from grace_dsl.perception.errors import PerceptionError
from grace_dsl.perception.types import SHARD_SCHEMA, ViewSample
from grace_dsl.perception.views import ViewConfig, stack_views


@dataclass(frozen=True)
class Shard:
    """A shard's arrays (``points``, ``params``, ``poses``, ``cameras``, ``joints``, ``seeds``,
    ``fixed``) and its meta."""

    arrays: dict[str, np.ndarray]
    meta: dict[str, Any]

    @property
    def concept(self) -> str:
        return str(self.meta["concept"])

    @property
    def param_names(self) -> tuple[str, ...]:
        return tuple(self.meta["param_names"])

    def __len__(self) -> int:
        return len(self.arrays["seeds"])

    def views(self) -> list[ViewSample]:
        """The shard's rows as ``ViewSample`` values."""
        a, names, joints = self.arrays, self.param_names, self.meta["joint_names"]
        return [
            ViewSample(
                concept=self.concept,
                points=a["points"][i],
                params=dict(zip(names, a["params"][i].tolist())),
                pose=a["poses"][i],
                camera_pose=a["cameras"][i],
                joints=dict(zip(joints, a["joints"][i].tolist())),
                seed=int(a["seeds"][i]),
                fixed=json.loads(str(a["fixed"][i])),
                part=str(self.meta.get("part", "")),
            )
            for i in range(len(self))
        ]


def _jsonable(value: Any) -> Any:
    return list(value) if isinstance(value, tuple) else value


def write_shard(
    path: str | Path, views: Sequence[ViewSample], joint_names: Sequence[str], config: ViewConfig
) -> Path:
    """Write ``views`` (all of one concept) to ``path`` (``.npz``); returns the path."""
    if not views:
        raise PerceptionError("a shard needs at least one view")
    concepts = {v.concept for v in views}
    if len(concepts) != 1:
        raise PerceptionError(f"a shard holds one concept's views, got {sorted(concepts)}")
    arrays = stack_views(views, joint_names)
    fixed = [{k: _jsonable(x) for k, x in v.fixed.items()} for v in views]
    shared = {k: x for k, x in fixed[0].items() if all(f.get(k) == x for f in fixed)}
    meta = {
        "schema": SHARD_SCHEMA,
        "concept": views[0].concept,
        "param_names": list(views[0].params),
        "joint_names": list(joint_names),
        "fixed": shared,
        "noise": {
            "sigma": config.noise.sigma,
            "dropout": config.noise.dropout,
            "flying": config.noise.flying,
        },
        "points_per_view": config.points,
        "part": config.part,
    }
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    tmp = path.with_name(path.name + ".tmp.npz")
    payload: dict[str, Any] = {
        **arrays,
        "fixed": np.array([json.dumps(f, sort_keys=True) for f in fixed]),
        "meta": np.array(json.dumps(meta)),
    }
    save: Any = np.savez_compressed  # its stubs type **kwds against allow_pickle
    save(tmp, **payload)
    tmp.replace(path)
    return path


def read_shard(path: str | Path) -> Shard:
    """A shard written by ``write_shard`` (or ``grace data gen``); ``PerceptionError`` names
    what is wrong with a file that is not one."""
    try:
        with np.load(Path(path), allow_pickle=False) as data:
            arrays = {k: data[k] for k in data.files if k != "meta"}
            meta = json.loads(str(data["meta"]))
    except (OSError, KeyError, ValueError) as exc:
        raise PerceptionError(f"{path}: not a view shard ({exc})") from None
    if meta.get("schema") != SHARD_SCHEMA:
        raise PerceptionError(f"{path}: schema {meta.get('schema')!r}, expected {SHARD_SCHEMA}")
    if "fixed" not in arrays:
        arrays["fixed"] = np.array(["{}"] * len(arrays["seeds"]))
    return Shard(arrays, meta)

"""The learned estimator's weights file: plain arrays and a JSON header, checked on load.

Why not a pickle: loading a pickle runs code from the file. A weights file here is a
``numpy.savez_compressed`` archive read with ``allow_pickle=False``: one array per tensor of the
network (float16, which halves the shipped size at no measurable cost in accuracy) and a
``meta`` string holding JSON:

    {"schema": "grace-eac.weights/1", "version": MODEL_VERSION, "concept": ..., "param_names":
     [...], "lo": [...], "hi": [...], "scale": ..., "points": ..., "config": {...},
     "sha256": ..., "trained": {...}}

``lo``/``hi`` normalize each parameter (0 and 1 at the ends of the training data's range),
``scale`` (m) divides the centred cloud, ``points`` is the cloud size the network was trained
on, ``config`` the network's size (``ModelConfig``), and ``sha256`` covers every tensor's name,
shape and bytes. Reading needs numpy only; torch comes in when a network is built from it.
"""

from __future__ import annotations

import hashlib
import json
from dataclasses import dataclass
from importlib import resources
from pathlib import Path
from typing import Any

import numpy as np

from grace_dsl.perception.errors import ModelWeightsError

WEIGHTS_SCHEMA = "grace-eac.weights/1"
#: Bumped whenever the network's code changes what a stored tensor means.
MODEL_VERSION = 1
TENSOR_PREFIX = "t/"
SUFFIX = ".npz"


@dataclass(frozen=True)
class WeightsFile:
    """A checked weights file: its header and its tensors (float32 numpy arrays)."""

    concept: str
    param_names: tuple[str, ...]
    lo: np.ndarray
    hi: np.ndarray
    scale: float
    points: int
    config: dict[str, Any]
    tensors: dict[str, np.ndarray]
    trained: dict[str, Any]
    path: str = ""


def digest(tensors: dict[str, np.ndarray]) -> str:
    """sha256 over the tensors' names, shapes, dtypes and bytes, in name order."""
    h = hashlib.sha256()
    for name in sorted(tensors):
        a = np.ascontiguousarray(tensors[name])
        h.update(f"{name}|{a.dtype.str}|{a.shape}|".encode())
        h.update(a.tobytes())
    return h.hexdigest()


def write_weights(path: str | Path, wf: WeightsFile) -> Path:
    """Write ``wf`` (tensors stored as float16) and return the path."""
    path = Path(path)
    if path.suffix != SUFFIX:
        raise ModelWeightsError(f"a weights file ends in {SUFFIX}: {path}")
    stored = {k: np.asarray(v, dtype=np.float16) for k, v in wf.tensors.items()}
    meta = {
        "schema": WEIGHTS_SCHEMA,
        "version": MODEL_VERSION,
        "concept": wf.concept,
        "param_names": list(wf.param_names),
        "lo": [float(x) for x in wf.lo],
        "hi": [float(x) for x in wf.hi],
        "scale": float(wf.scale),
        "points": int(wf.points),
        "config": wf.config,
        "sha256": digest(stored),
        "trained": wf.trained,
    }
    path.parent.mkdir(parents=True, exist_ok=True)
    arrays: dict[str, Any] = {TENSOR_PREFIX + k: v for k, v in stored.items()}
    arrays["meta"] = np.array(json.dumps(meta, sort_keys=True))
    with path.open("wb") as fh:
        np.savez_compressed(fh, **arrays)
    return path


def read_weights(path: str | Path, concept: str | None = None) -> WeightsFile:
    """Read and check a weights file; ``concept`` (if given) must be the one it was trained on.

    Raises ``ModelWeightsError`` for a missing or unreadable file, another schema or model
    version, another concept, a malformed header or a checksum that does not match."""
    path = Path(path)
    if not path.is_file():
        raise ModelWeightsError(f"no weights file at {path}")
    try:
        with np.load(path, allow_pickle=False) as z:
            arrays = {k: z[k] for k in z.files}
    except Exception as exc:  # zip, npy or pickle-refusal errors: all mean "not ours"
        raise ModelWeightsError(f"{path} is not a weights file ({exc})") from exc
    meta = _meta(arrays.pop("meta", None), path)
    tensors = {k[len(TENSOR_PREFIX) :]: v for k, v in arrays.items() if k.startswith(TENSOR_PREFIX)}
    if meta["sha256"] != digest(tensors):
        raise ModelWeightsError(f"{path}: checksum mismatch (the file was altered or truncated)")
    if concept is not None and meta["concept"] != concept:
        raise ModelWeightsError(
            f"{path} holds weights for {meta['concept']}, not {concept}; "
            f"train them with `grace train {concept} -o FILE`"
        )
    names = tuple(meta["param_names"])
    if not (len(meta["lo"]) == len(meta["hi"]) == len(names)):
        raise ModelWeightsError(f"{path}: lo, hi and param_names differ in length")
    return WeightsFile(
        concept=meta["concept"],
        param_names=names,
        lo=np.asarray(meta["lo"], float),
        hi=np.asarray(meta["hi"], float),
        scale=float(meta["scale"]),
        points=int(meta["points"]),
        config=dict(meta["config"]),
        tensors={k: v.astype(np.float32) for k, v in tensors.items()},
        trained=dict(meta.get("trained", {})),
        path=str(path),
    )


def _meta(raw: np.ndarray | None, path: Path) -> dict[str, Any]:
    """The header, checked for the schema, the version and every key a loader reads."""
    if raw is None or raw.dtype.kind != "U":
        raise ModelWeightsError(f"{path}: no header (meta); not a {WEIGHTS_SCHEMA} file")
    try:
        meta = json.loads(str(raw))
    except json.JSONDecodeError as exc:
        raise ModelWeightsError(f"{path}: the header is not JSON ({exc})") from exc
    if not isinstance(meta, dict) or meta.get("schema") != WEIGHTS_SCHEMA:
        got = meta.get("schema") if isinstance(meta, dict) else None
        raise ModelWeightsError(f"{path}: schema {got!r}, expected {WEIGHTS_SCHEMA!r}")
    if meta.get("version") != MODEL_VERSION:
        raise ModelWeightsError(
            f"{path}: model version {meta.get('version')!r}, this code reads {MODEL_VERSION}; "
            "retrain with `grace train`"
        )
    missing = [k for k in ("concept", "param_names", "lo", "hi", "scale", "points", "config",
                           "sha256") if k not in meta]  # fmt: skip
    if missing:
        raise ModelWeightsError(f"{path}: the header lacks {', '.join(missing)}")
    return meta


def shipped_path(concept: str) -> Path:
    """Where the package keeps the pretrained weights of ``concept`` (may not exist)."""
    return Path(str(resources.files("grace_dsl.perception") / "weights" / f"{concept}{SUFFIX}"))


def shipped_concepts() -> tuple[str, ...]:
    """The concepts the package ships pretrained weights for."""
    folder = Path(str(resources.files("grace_dsl.perception") / "weights"))
    if not folder.is_dir():
        return ()
    return tuple(sorted(p.stem for p in folder.glob(f"*{SUFFIX}")))

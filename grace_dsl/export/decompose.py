"""Convex decomposition of a mesh that has no analytic split (CoACD), seeded and cached.

Only boolean results that are not a box minus axis-aligned boxes come here (e.g. a shell cut
from a cylinder sector). CoACD is deterministic for a given seed; its parts are cached on disk
under ``<cache>/convex/`` keyed by the mesh bytes, the settings and the seed, because one run
takes seconds and an export is repeated for every episode. The cache holds plain arrays
(``.npz`` read without pickle), so it needs no trust beyond the numbers.
"""

from __future__ import annotations

import hashlib
import logging
import os
from typing import Any

import numpy as np
import trimesh

from grace_dsl.cache import cache_dir
from grace_dsl.runtime.errors import GraceError

log = logging.getLogger(__name__)

THRESHOLD = 0.04  # CoACD's concavity bound (relative to the mesh's size)
MAX_HULLS = 16
SEED = 0
_VERSION = 1  # bump to invalidate cached decompositions


class DecompositionError(GraceError):
    """A mesh that needs a convex decomposition when CoACD is not installed."""


def convex_decomposition(mesh: trimesh.Trimesh, seed: int = SEED) -> list[trimesh.Trimesh]:
    """Convex parts whose union approximates ``mesh`` (CoACD, ``THRESHOLD``), cached."""
    key = _key(mesh, seed)
    path = cache_dir() / "convex" / f"{key}.npz"
    if path.is_file():
        try:
            return _load(path)
        except (OSError, ValueError, KeyError):
            log.warning("ignoring an unreadable cached decomposition %s", path)
    parts = _run(mesh, seed)
    path.parent.mkdir(parents=True, exist_ok=True)
    tmp = path.with_suffix(f".{os.getpid()}.tmp.npz")  # one writer per process
    arrays: dict[str, Any] = {f"v{i}": np.asarray(p.vertices) for i, p in enumerate(parts)}
    arrays |= {f"f{i}": np.asarray(p.faces) for i, p in enumerate(parts)}
    np.savez(tmp, **arrays)
    tmp.replace(path)  # atomic: parallel episodes may write the same entry
    return parts


def _key(mesh: trimesh.Trimesh, seed: int) -> str:
    h = hashlib.sha256()
    h.update(np.ascontiguousarray(mesh.vertices, dtype=np.float64).tobytes())
    h.update(np.ascontiguousarray(mesh.faces, dtype=np.int64).tobytes())
    h.update(f"{THRESHOLD}/{MAX_HULLS}/{seed}/{_VERSION}".encode())
    return h.hexdigest()[:32]


def _load(path: object) -> list[trimesh.Trimesh]:
    with np.load(path, allow_pickle=False) as data:  # type: ignore[arg-type]
        n = len(data.files) // 2
        return [trimesh.Trimesh(data[f"v{i}"], data[f"f{i}"], process=False) for i in range(n)]


def _run(mesh: trimesh.Trimesh, seed: int) -> list[trimesh.Trimesh]:
    try:
        import coacd
    except ImportError:
        raise DecompositionError(
            "a non-convex boolean shape needs a convex decomposition for collision: "
            "install the simulation extra (pip install 'grace-dsl[sim]', which brings coacd)"
        ) from None
    coacd.set_log_level("error")
    source = coacd.Mesh(np.asarray(mesh.vertices, float), np.asarray(mesh.faces, np.int64))
    parts = coacd.run_coacd(
        source, threshold=THRESHOLD, max_convex_hull=MAX_HULLS, seed=seed, preprocess_mode="off"
    )
    return [trimesh.Trimesh(v, f, process=False).convex_hull for v, f in parts]

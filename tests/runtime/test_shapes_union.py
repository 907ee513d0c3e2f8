"""``inst.mesh()`` is one closed solid, the boolean union of the instance's shapes: its
``contains`` agrees with the sign of ``inst.sdf``, it is watertight and its volume matches a
Monte-Carlo estimate from ``sdf``, on every concept of the standard library at a random draw.
The concatenation (``instance_mesh_concat``) disagreed with ``sdf`` on up to 48% of points."""

from __future__ import annotations

import math

import numpy as np
import pytest
import trimesh

import grace_dsl as eac
from grace_dsl.runtime.draws import draw_valid
from grace_dsl.runtime.errors import RequirementError
from grace_dsl.runtime.shapes import instance_mesh_concat, instance_meshes
from grace_dsl.runtime.verify import concept_seed, draw_params, random_pose
from tests.meshes import inside

LIB = eac.load_library
FAR = 1.5e-3  # m: a 64-gon's chords stay within ~1.2e-3 r of the true surface
N_CONTAINS = 300  # points whose containment is checked by winding number
N_VOLUME = 100_000


def _concepts() -> list[str]:
    lib = LIB()
    return [n for n in lib if lib[n].entry["kind"] == "concept"]


def random_instance(concept: eac.Concept, seed: int) -> eac.Instance:
    """A draw inside every range that satisfies the requirements, at random joints and pose:
    uniform first, then repaired as ``eacc verify`` repairs its draws (about 2% of uniform
    draws of ``StorageFurniture`` are valid, and 200 uniform tries found none)."""
    rng = np.random.default_rng(seed)
    for attempt in range(400):
        try:
            params = (
                draw_params(concept, rng)
                if attempt < 200
                else draw_valid(concept, rng, concept.params, draw_params)
            )
            inst = concept.instantiate(pose=random_pose(rng), params=params)
        except RequirementError:
            continue
        joints = {
            n: float(rng.uniform(lo, hi)) if math.isfinite(hi - lo) else float(rng.uniform(-3, 3))
            for n, (lo, hi) in inst.joint_limits().items()
        }
        return concept.instantiate(pose=inst.pose, joints=joints, **inst.params)
    raise AssertionError(f"no valid draw of {concept.name}")


@pytest.mark.slow
@pytest.mark.parametrize("name", _concepts())
def test_union_mesh_is_the_solid_sdf_describes(name: str) -> None:
    inst = random_instance(LIB()[name], concept_seed(7, name))
    mesh = inst.mesh()
    assert mesh.is_watertight and mesh.is_winding_consistent and mesh.volume > 0
    lo, hi = mesh.bounds
    rng = np.random.default_rng(concept_seed(8, name))
    pad = 0.1 * (hi - lo) + 0.01
    # half the points near the surface, where containment is hard; half anywhere in the box
    near = inst.sample_surface(N_CONTAINS // 2, seed=1) + rng.normal(0, 0.01, (N_CONTAINS // 2, 3))
    pts = np.concatenate([near, rng.uniform(lo - pad, hi + pad, (N_CONTAINS // 2, 3))])
    d = inst.sdf(pts)
    far = np.abs(d) > FAR
    assert far.sum() > N_CONTAINS / 3
    # the winding number, not trimesh's ray test: a ray that grazes an edge is cast again
    # along a direction from numpy's global random state, and RangeHood's union then came out
    # outside at a point 9.8 mm deep in some runs (the mesh was right: winding number 1)
    agree = inside(mesh, pts[far]) == (d[far] < 0)
    assert agree.all(), (name, pts[far][~agree], d[far][~agree])
    box = rng.uniform(lo, hi, (N_VOLUME, 3))
    share = float(np.mean(inst.sdf(box) < 0))
    size = float(np.prod(hi - lo))
    sigma = size * math.sqrt(share * (1 - share) / N_VOLUME)
    assert abs(mesh.volume - size * share) <= 5 * sigma + 0.01 * mesh.volume, (
        mesh.volume,
        size * share,
        sigma,
    )


def test_concatenation_keeps_every_piece_and_the_union_removes_overlaps() -> None:
    inst = LIB()["ChestOfDrawers"].instantiate()
    pieces = instance_meshes(inst)
    soup, union = instance_mesh_concat(inst), inst.mesh()
    assert len(soup.faces) == sum(len(m.faces) for m in pieces)
    assert union.volume < soup.volume - 0.1  # the drawers sit inside the carcass
    assert union.volume == pytest.approx(
        trimesh.boolean.union(pieces, engine="manifold").volume, rel=1e-12
    )

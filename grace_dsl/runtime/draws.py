"""Random parameter draws that satisfy a concept's requirements.

Drawing every parameter uniformly and rejecting the draws that break a ``require`` wastes most
draws of a concept whose sizes depend on each other: in ``StorageFurniture`` a drawer's travel
must fit its tray, the tray the carcass, each handle its front, so only about 2% of independent
draws were valid.  ``draw_valid`` repairs a draw instead of rejecting it: while requirements
fail, it redraws one parameter that each failing requirement depends on (a random one, from its
own range, with the same end-point weighting as the first draw), up to ``REPAIR_ROUNDS`` rounds.
Only parameters are changed, never the ranges, so every value stays one a plain draw could give;
the repaired draws are biased towards the feasible region's interior, which is what a verifier
wants to exercise.

Which parameters a requirement depends on is found numerically, once per concept and range
mode: each parameter is redrawn alone at a few random points and the requirements whose
residuals change depend on it.  That sees through ``let`` chains, host bindings of nested
parts and masking, which the requirement's own text does not.
"""

from __future__ import annotations

from collections.abc import Callable, Mapping, Sequence
from typing import TYPE_CHECKING, Any

import numpy as np

from grace_dsl.runtime.errors import ParameterError

if TYPE_CHECKING:
    from grace_dsl.runtime.concept import ParamSpec
    from grace_dsl.runtime.library import Concept

REPAIR_ROUNDS = 60  # redraw rounds before a draw is handed over as it is
PROBES = 3  # random points at which each parameter's influence is measured

Draw = Callable[[Any, np.random.Generator, Sequence[Any]], dict[str, Any]]

_DEPENDS: dict[tuple[int, str, tuple[str, ...]], list[list[str]]] = {}


def draw_valid(
    concept: Concept,
    rng: np.random.Generator,
    specs: Sequence[ParamSpec],
    draw: Draw,
    ranges: str = "typical",
) -> dict[str, Any]:
    """A draw of every parameter (``draw(concept, rng, specs)``), repaired until it meets the
    requirements or ``REPAIR_ROUNDS`` rounds have passed."""
    values = draw(concept, rng, specs)
    requires = concept.entry["requires"]
    if not requires:
        return values
    depends = _dependencies(concept, rng, specs, draw, ranges)
    by_name = {s.name: s for s in specs}
    for _ in range(REPAIR_ROUNDS):
        failed = _failed(concept, values, ranges)
        if failed is None or not failed:
            break
        names = {str(rng.choice(depends[i])) for i in failed if i < len(depends) and depends[i]}
        if not names:
            break
        values.update(draw(concept, rng, [by_name[n] for n in sorted(names)]))
    return values


def _failed(concept: Concept, values: Mapping[str, Any], ranges: str) -> list[int] | None:
    """Indices of the requirements ``values`` break; None when they cannot be evaluated."""
    residuals = _residuals(concept, values, ranges)
    if residuals is None:
        return None
    _, holds = residuals
    return [i for i, h in enumerate(holds) if h != 1.0]


def _residuals(
    concept: Concept, values: Mapping[str, Any], ranges: str
) -> tuple[np.ndarray, list[float]] | None:
    packer = concept._valid_packer if ranges == "valid" else concept._packer
    try:
        p = packer.pack(values, concept.name)
    except ParameterError:
        return None
    r, holds = concept.function("requires")(p)
    return np.asarray(r, float).ravel(), np.asarray(holds, float).ravel().tolist()


def _dependencies(
    concept: Concept,
    rng: np.random.Generator,
    specs: Sequence[ParamSpec],
    draw: Draw,
    ranges: str,
) -> list[list[str]]:
    """Per requirement, the parameters whose value changes its residual (cached)."""
    key = (id(concept), ranges, tuple(s.name for s in specs))
    if key in _DEPENDS:
        return _DEPENDS[key]
    n = len(concept.entry["requires"])
    found: list[set[str]] = [set() for _ in range(n)]
    probe = np.random.default_rng(int(rng.integers(2**32)))  # the caller's stream stays put
    for _ in range(PROBES):
        base = draw(concept, probe, specs)
        start = _residuals(concept, base, ranges)
        if start is None:
            continue
        for spec in specs:
            moved = dict(base)
            moved.update(draw(concept, probe, [spec]))
            after = _residuals(concept, moved, ranges)
            if after is None:
                continue
            changed = ~np.isclose(start[0], after[0], rtol=0.0, atol=1e-12, equal_nan=True)
            for i in np.flatnonzero(changed):
                found[i].add(spec.name)
    _DEPENDS[key] = [sorted(s) for s in found]
    return _DEPENDS[key]

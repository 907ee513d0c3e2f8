"""`eacc verify`'s checks on `StorageFurniture` with every layout covered.

``eacc verify`` draws the layout parameters at random like the others (and repairs a draw that
breaks a requirement), so a layout may come up rarely or never. Here the discrete parameters
of each draw are set to the next layout of ``LAYOUTS`` in turn (the continuous ones stay the
verifier's draws, redrawn until the layout's requirements hold), and the report counts the
draws per layout. Run: ``.venv/bin/python docs/storage_furniture_verify.py [DRAWS]``.
"""

from __future__ import annotations

import collections
import json
import sys
from typing import Any

import grace_dsl as eac
from grace_dsl.runtime import verify

# rows, cols, doors, blind, stand. A single door is drawn with either hinge side (and a blind
# panel on either side); a pair of doors hinges at the outer edges, which is door [0] on the
# left (the concept requires it), so its hinge side is set here rather than redrawn.
LAYOUTS = [
    {"rows": r, "cols": c, "doors": d, "blind": b, "stand": s}
    | ({"hinge_side": "left"} if d == 2 else {})
    for r, c, d, b in [
        (1, 1, 0, 0),
        (3, 1, 0, 0),
        (4, 1, 0, 0),
        (1, 2, 0, 0),
        (1, 3, 0, 0),
        (2, 2, 0, 0),
        (1, 1, 1, 0),
        (1, 2, 2, 0),
        (2, 3, 2, 0),
        (0, 1, 1, 0),
        (0, 1, 2, 0),
        (0, 1, 1, 1),
        (1, 1, 1, 1),
    ]
    for s in ("plinth", "legs")
]


class Cycling:
    """The concept, with each accepted draw's layout set to the next of ``LAYOUTS``."""

    def __init__(self, concept: eac.Concept):
        self._concept = concept
        self.next = 0
        self.seen: collections.Counter[str] = collections.Counter()

    def __getattr__(self, name: str) -> Any:
        return getattr(self._concept, name)

    def instantiate(self, *args: Any, params: dict[str, Any], **kw: Any) -> Any:
        layout = LAYOUTS[self.next % len(LAYOUTS)]
        inst = self._concept.instantiate(*args, params=params | layout, **kw)
        self.next += 1
        self.seen[json.dumps(layout)] += 1
        return inst


def main(argv: list[str] | None = None) -> int:
    args = sys.argv[1:] if argv is None else argv
    draws = int(args[0]) if args else 2 * len(LAYOUTS)
    concept = eac.load_library()["StorageFurniture"]
    cycling = Cycling(concept)
    seed = verify.concept_seed(0, concept.name)
    report = verify.verify_concept(cycling, draws=draws, seed=seed)  # type: ignore[arg-type]
    print(json.dumps(report.to_json(), indent=1))
    for layout, n in sorted(cycling.seen.items()):
        print(n, layout)
    print(f"{len(cycling.seen)} of {len(LAYOUTS)} layouts drawn; ok: {report.ok}")
    return 0 if report.ok else 1


if __name__ == "__main__":
    raise SystemExit(main())

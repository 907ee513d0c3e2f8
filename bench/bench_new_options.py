"""Which episodes would a hand's chosen option change by grasp families added to the library?
No physics needed.

An episode (``bench/bench_sim.py``) acts with the first feasible option of ``inst.rank``. A grasp
family added to a concept changes no other option's verdict, so the option a library without it
would choose is the first feasible one of the others. This draws every episode of a run as the
bench does and counts, per category and task, the episodes whose option the added families
change (for the Panda, the check that families added for other hands leave its choices alone).

    python bench/bench_new_options.py --categories Drawer --new hook_top[0] --episodes 25
    python bench/bench_new_options.py --smoke
"""

from __future__ import annotations

import sys
import time
from pathlib import Path
from typing import Any

sys.path.insert(0, str(Path(__file__).resolve().parent))
from bench_rank_order import run  # noqa: E402  (the draws, the command line, the table)

ROOT = Path(__file__).resolve().parent.parent
RESULTS = ROOT / "bench" / "results" / "new_options.json"
# the families condfam added (issue 13, the other hands), per concept
ADDED = {
    "MirrorCabinet": ("hook_side", "hook_top"),
    "CabinetDrawer": ("hook_top",),
    "Drawer": ("hook_top[0]",),
    "LidBox": ("lift_under",),
    "Laptop": ("lift_under",),
}


def main(argv: list[str] | None = None) -> int:
    return run(argv, __doc__, "bench_new_options.py", RESULTS, list(ADDED), added_choices)


def added_choices(concept: str, options: list[Any]) -> tuple[str | None, str | None]:
    """The first feasible option without the families added to ``concept``, and with them."""
    added = ADDED.get(concept, ())
    old = next((o.grasp for o in options if o.feasible and o.grasp not in added), None)
    return old, next((o.grasp for o in options if o.feasible), None)


if __name__ == "__main__":
    t0 = time.perf_counter()
    code = main()
    print(f"{time.perf_counter() - t0:.0f} s")
    sys.exit(code)

"""How many random draws of a concept satisfy its requirements: independent uniform draws (as
``eacc verify`` drew them before) against draws repaired by ``runtime/draws.py``.

Run: ``.venv/bin/python bench/bench_draw_yield.py [--n 100] [--seed 0] [--out FILE] [--smoke]``
(writes bench/results/draw_yield.json; ``--smoke`` draws 5 of each).
"""

from __future__ import annotations

import argparse
import json
import time
from pathlib import Path

import numpy as np
from rich.progress import track

import grace_dsl as eac
from grace_dsl.runtime.draws import draw_valid
from grace_dsl.runtime.verify import draw_params

CONCEPTS = ("StorageFurniture", "BoardChest3", "BoardCabinet", "Drawer", "DoorLeaf")


def _yield(c: eac.Concept, n: int, seed: int, repair: bool) -> dict[str, float]:
    rng = np.random.default_rng(seed)
    valid, start = 0, time.perf_counter()
    for _ in range(n):
        values = draw_valid(c, rng, c.params, draw_params) if repair else draw_params(c, rng)
        try:
            c.instantiate(**values)
            valid += 1
        except eac.RequirementError:
            continue
    return {"valid": valid, "draws": n, "rate": valid / n, "seconds": time.perf_counter() - start}


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__)
    ap.add_argument("--n", type=int, default=100, help="draws per concept and mode")
    ap.add_argument("--seed", type=int, default=0)
    ap.add_argument("--out", type=Path, default=Path("bench/results/draw_yield.json"))
    ap.add_argument("--smoke", action="store_true", help="5 draws of each")
    args = ap.parse_args()
    n = 5 if args.smoke else args.n
    lib = eac.load_library()
    result: dict[str, dict[str, dict[str, float]]] = {}
    for name in track(CONCEPTS, description="draws"):
        c = lib[name]
        result[name] = {
            "uniform": _yield(c, n, args.seed, repair=False),
            "repaired": _yield(c, n, args.seed, repair=True),
        }
        u, r = result[name]["uniform"], result[name]["repaired"]
        print(f"{name:18s} uniform {u['rate']:6.1%}  repaired {r['rate']:6.1%}  ({n} draws)")
    args.out.parent.mkdir(parents=True, exist_ok=True)
    args.out.write_text(json.dumps(result, indent=2) + "\n", encoding="utf-8")


if __name__ == "__main__":
    main()

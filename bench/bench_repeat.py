"""Masking against one unit per count: how a concept with ``for i in 0..n`` should compile.

Run: ``.venv/bin/python bench/bench_repeat.py [--max-count 5] [--repeats 200] [--vm]
[--out FILE] [--smoke]``. The concept is the chest of ``docs/examples/chest_of_drawers.eac``
(n drawers, each with a bar or ring handle). *Masking* compiles it once, unrolled to the largest
count, and the runtime hides the copies an instance lacks; *per count* compiles one concept for
each count (the loop bound a constant), as if the count were fixed at build time. For both the
script measures the cold build (wall and CPU seconds of a child process, the C compiler
included; the imported standard library is built before the clock starts), the size of the
compiled units (manifest ``unit.json``, serialized functions, native library) and the time an
instance needs for what a robot asks of it: instantiate at count k, then every drawer's handle
grasp and link pose (CPU time, the best of ten batches). Writes bench/results/repeat.json.
``--smoke``: counts up to 2, CasADi's VM.
"""

from __future__ import annotations

import argparse
import json
import os
import platform
import re
import resource
import subprocess
import sys
import tempfile
import time
from pathlib import Path
from typing import Any

from grace_dsl.compiler.build import build
from grace_dsl.compiler.resolve import stdlib_dir
from grace_dsl.runtime.library import Concept, Library

ROOT = Path(__file__).resolve().parents[1]
EXAMPLE = ROOT / "docs" / "examples" / "chest_of_drawers.eac"
RESULTS = Path(__file__).resolve().parent / "results" / "repeat.json"
COUNT = re.compile(r"param n : int in \[1, 5\] = 3")


def _cpu() -> float:
    """CPU seconds of this process and its finished children (the C compiler)."""
    own = resource.getrusage(resource.RUSAGE_SELF)
    kids = resource.getrusage(resource.RUSAGE_CHILDREN)
    return own.ru_utime + own.ru_stime + kids.ru_utime + kids.ru_stime


def _source(lo: int, hi: int, name: str) -> str:
    text = EXAMPLE.read_text(encoding="utf-8")
    assert COUNT.search(text), "the example's count changed; update the benchmark"
    text = COUNT.sub(f"param n : int in [{lo}, {hi}] = {lo}", text)
    return text.replace("concept ChestOfNDrawers", f"concept {name}")


def _build(files: list[Path], cache: Path, native: bool) -> tuple[dict[str, Concept], dict]:
    """Build in a child process (so its CPU time, compilers included, is counted once it
    exits), then load the cached result here."""
    code = (
        "import sys; from pathlib import Path; from grace_dsl.compiler.build import build; "
        "r = build([Path(a) for a in sys.argv[3:]], Path(sys.argv[1]), "
        "use_native=sys.argv[2] == '1'); sys.exit(0 if r.ok else 1)"
    )
    argv = [sys.executable, "-c", code, str(cache), "1" if native else "0", *map(str, files)]
    wall, cpu = time.perf_counter(), _cpu()
    subprocess.run(argv, check=True, env={**os.environ, "PYTHONPATH": str(ROOT)})
    wall, cpu = time.perf_counter() - wall, _cpu() - cpu
    result = build(files, cache, use_native=native)
    assert result.ok, result.diagnostics
    lib = Library(result.units, result)
    sizes = {"unit_json": 0, "functions_json": 0, "native": 0}
    for unit in result.units:
        if Path(unit.file).parent != files[0].parent:
            continue  # the standard library's units, built before the clock started
        for f in unit.dir.iterdir():
            if f.name == "unit.json":
                sizes["unit_json"] += f.stat().st_size
            elif f.name == "functions.json":
                sizes["functions_json"] += f.stat().st_size
            elif f.suffix == ".so":
                sizes["native"] += f.stat().st_size
    names = {n: lib[n] for n in lib if n.startswith("Chest")}
    return names, {"wall_s": round(wall, 2), "cpu_s": round(cpu, 2), "bytes": sizes}


def _queries(concept: Concept, k: int, repeats: int) -> float:
    """Microseconds for instantiate(n=k) plus every drawer's handle grasp and link pose."""
    for _ in range(3):  # load the evaluators
        _ask(concept, k)
    batch = max(1, repeats // 10)
    best = float("inf")  # CPU time, the least disturbed of ten batches: the machine is shared
    for _ in range(10):
        t0 = time.process_time()
        for _ in range(batch):
            _ask(concept, k)
        best = min(best, (time.process_time() - t0) / batch)
    return best * 1e6


def _ask(concept: Concept, k: int) -> Any:
    inst = concept.instantiate(n=k)
    for i in range(k):
        inst.grasp(f"handle[{i}].pull")
        inst.link_pose(f"drawer[{i}]")
    return inst


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--max-count", type=int, default=5)
    ap.add_argument("--repeats", type=int, default=200)
    ap.add_argument("--vm", action="store_true", help="no native code: CasADi's VM only")
    ap.add_argument("--out", type=Path, default=RESULTS)
    ap.add_argument("--smoke", action="store_true", help="counts up to 2, VM: checks it runs")
    args = ap.parse_args()
    if args.smoke:
        args.max_count, args.repeats, args.vm = 2, 5, True
    top = args.max_count
    with tempfile.TemporaryDirectory() as tmp:
        work = Path(tmp)
        cache = work / "cache"
        build([stdlib_dir() / "handles.eac"], cache, use_native=not args.vm)  # the imports
        masked_file = work / "masked.eac"
        masked_file.write_text(_source(1, top, "ChestMasked"), encoding="utf-8")
        masked, masked_build = _build([masked_file], cache, not args.vm)
        files = []
        for k in range(1, top + 1):
            f = work / f"count{k}.eac"
            f.write_text(_source(k, k, f"ChestCount{k}"), encoding="utf-8")
            files.append(f)
        per_count, per_build = _build(files, cache, not args.vm)
        rows = []
        for k in range(1, top + 1):
            rows.append(
                {
                    "count": k,
                    "masked_us": round(_queries(masked["ChestMasked"], k, args.repeats), 1),
                    "per_count_us": round(
                        _queries(per_count[f"ChestCount{k}"], k, args.repeats), 1
                    ),
                }
            )
    result = {
        "max_count": top,
        "native": not args.vm,
        "masked": {"build": masked_build},
        "per_count": {"build": per_build},
        "queries": rows,
        "machine": platform.machine(),
        "python": sys.version.split()[0],
        "load": os.getloadavg()[0],
    }
    print(json.dumps(result, indent=1))
    args.out.parent.mkdir(parents=True, exist_ok=True)
    args.out.write_text(json.dumps(result, indent=1) + "\n", encoding="utf-8")
    return 0


if __name__ == "__main__":
    sys.exit(main())

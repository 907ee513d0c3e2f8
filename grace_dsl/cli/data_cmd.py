"""``grace data gen CONCEPT... -n N -o DIR``: synthetic views of concepts, in shards.

Each concept gets ``N`` views (random parameters, joints and camera; the target's partial cloud
with its ground truth), written as ``DIR/CONCEPT-KKKK.npz`` (``perception.types.SHARD_SCHEMA``).
The same ``--seed`` gives the same arrays whatever ``--workers``. Errors a user can cause (an
unknown concept, a bad number, an unwritable directory) are one line and exit code 1.
"""

from __future__ import annotations

import argparse
import os
import time
from collections.abc import Callable, Iterator
from contextlib import contextmanager
from typing import Any

from grace_dsl.cli.output import console, error, print_json, print_text
from grace_dsl.runtime.errors import GraceError


def add_data_arguments(p: argparse.ArgumentParser) -> None:
    sub = p.add_subparsers(dest="data_command")
    gen = sub.add_parser("gen", help="synthetic views of concepts for training and benchmarks")
    gen.add_argument("concepts", nargs="+", metavar="CONCEPT", help="standard-library concepts")
    gen.add_argument("-n", type=int, default=256, help="views per concept (256)")
    gen.add_argument("--points", type=int, default=1024, help="points per view (1024)")
    gen.add_argument("--noise", type=float, default=0.002, help="depth noise sigma, m (0.002)")
    gen.add_argument("--dropout", type=float, default=0.0, help="share of pixels lost (0)")
    gen.add_argument("--flying", type=float, default=0.0, help="share of edge pixels flying (0)")
    gen.add_argument("--part", default="", help="keep only this link's points (default: all)")
    gen.add_argument("--seed", type=int, default=0, help="dataset seed (0)")
    gen.add_argument("--workers", type=int, default=0, help="processes (default: the usable cores)")
    gen.add_argument("--shard-size", type=int, default=256, help="views per shard file (256)")
    gen.add_argument("-o", "--output", required=True, metavar="DIR", help="where shards go")
    gen.add_argument("--json", action="store_true", help="print the shards written as JSON")


def run_data(args: Any) -> int:
    """The body of ``grace data``; 0 on success, 1 with one line on stderr otherwise."""
    if args.data_command != "gen":
        error("grace data: give a subcommand: grace data gen CONCEPT... -n N -o DIR")
        return 2
    try:
        return _gen(args)
    except (GraceError, OSError, ValueError) as exc:
        error(str(exc).splitlines()[0] if str(exc) else type(exc).__name__)
        return 1


def _gen(args: Any) -> int:
    import grace_dsl as eac
    from grace_dsl.perception.camera import DepthNoise
    from grace_dsl.perception.dataset import generate_dataset
    from grace_dsl.perception.views import ViewConfig

    lib = eac.load_library()
    config = ViewConfig(
        points=args.points,
        noise=DepthNoise(sigma=args.noise, dropout=args.dropout, flying=args.flying),
        part=args.part,
    )
    workers = args.workers or max(1, len(os.sched_getaffinity(0)))
    start = time.perf_counter()
    with _progress(len(args.concepts) * args.n) as progress:
        paths = generate_dataset(
            lib,
            args.concepts,
            args.n,
            args.output,
            seed=args.seed,
            config=config,
            workers=workers,
            shard_size=args.shard_size,
            progress=progress,
        )
    seconds = time.perf_counter() - start
    if args.json:
        print_json({"shards": [str(p) for p in paths], "seconds": seconds})
    else:
        views = len(args.concepts) * args.n
        print_text(
            f"{views} views in {len(paths)} shards under {args.output} "
            f"({seconds:.1f} s, {1000 * seconds / views:.0f} ms per view, {workers} workers)"
        )
    return 0


@contextmanager
def _progress(total: int) -> Iterator[Callable[[int], None] | None]:
    """A rich bar over the views on a terminal (stderr), nothing when piped."""
    err = console(stderr=True)
    if not err.is_terminal:
        yield None
        return
    from rich.progress import BarColumn, MofNCompleteColumn, Progress, TimeRemainingColumn

    columns = (BarColumn(), MofNCompleteColumn(), TimeRemainingColumn())
    with Progress("drawing views", *columns, console=err, transient=True) as bar:
        task = bar.add_task("views", total=total)
        yield lambda k: bar.advance(task, k)

"""``grace train CONCEPT -o WEIGHTS``: train the learned estimator for one concept.

The views come from shards (``--data DIR``, written by ``grace data gen``) or are drawn here
(``--generate N``, seeded by ``--seed``); the run shows a progress bar per stage, writes a
checkpoint next to the output after each epoch (an interrupted run resumes from it) and prints
the held-out error per parameter (``--json``: the whole result). Exit codes: 0 trained, 1 a bad
argument, missing torch or a data problem, each reported in one line.
"""

from __future__ import annotations

import argparse
import shlex
from pathlib import Path
from typing import Any

from grace_dsl.cli.output import error, print_json, print_table
from grace_dsl.runtime.errors import GraceError


def register(sub: Any) -> None:
    """Add ``grace train`` to the ``grace`` subcommands (its handler rides on the args)."""
    p = sub.add_parser("train", help="train the learned parameter estimator for one concept")
    p.add_argument("concept", help="a concept of the standard library, e.g. CabinetDrawer")
    src = p.add_mutually_exclusive_group(required=True)
    src.add_argument("--data", metavar="DIR", help="shards of the concept's views")
    src.add_argument("--generate", metavar="N", type=int, help="draw N views here")
    p.add_argument("--epochs", type=int, default=30, help="passes over the views (30)")
    p.add_argument("--points", type=int, default=512, help="points per cloud (512)")
    p.add_argument("--batch", type=int, default=32, help="clouds per step (32)")
    p.add_argument("--lr", type=float, default=2e-3, help="peak learning rate (2e-3)")
    p.add_argument("--subsets", type=int, default=1, help="point subsets per view (1)")
    p.add_argument("--seed", type=int, default=0, help="views, split, order and weights (0)")
    p.add_argument("--threads", type=int, default=1, help="torch threads (1: deterministic)")
    p.add_argument("--noise", type=float, default=0.002, help="depth noise of drawn views (m)")
    p.add_argument("-o", "--output", required=True, metavar="WEIGHTS", help="the .npz to write")
    p.add_argument("--json", action="store_true", help="print the result as JSON")
    p.set_defaults(handler=run_train)


def run_train(args: argparse.Namespace) -> int:
    try:
        return _run(args)
    except ImportError as exc:
        error(f"grace train needs torch (pip install 'grace-dsl[learn]'): {exc}")
        return 1
    except (GraceError, OSError, ValueError) as exc:
        error(str(exc).splitlines()[0] if str(exc) else type(exc).__name__)
        return 1


def _run(args: argparse.Namespace) -> int:
    import torch  # noqa: F401  (fail early, before drawing views, when torch is missing)

    from grace_dsl.perception.train import TrainConfig, load_shards, train, views_to_arrays

    if args.generate is not None:
        data = views_to_arrays(_generate(args.concept, args.generate, args.seed, args.noise))
    else:
        data = load_shards(args.data, args.concept)
    cfg = TrainConfig(
        epochs=args.epochs, batch=args.batch, lr=args.lr, points=args.points, seed=args.seed,
        threads=args.threads, subsets=args.subsets,
    )  # fmt: skip
    command = _command(args)
    with _bar(not args.json) as bar:
        task = bar.add_task(f"training {data.concept}", total=cfg.epochs)

        def progress(epoch: int, epochs: int, row: dict[str, float]) -> None:
            bar.update(task, completed=epoch, description=f"val loss {row['val']:.4f}")

        result = train(data, Path(args.output), cfg, command=command, progress=progress)
    if args.json:
        print_json({"weights": str(result.path), "views": len(data), "val_mae": result.val_mae,
                    "history": result.history, "seconds": result.seconds})  # fmt: skip
        return 0
    rows = [(n, f"{v:.5f}") for n, v in result.val_mae.items()]
    print_table(f"{data.concept}: held-out mean absolute error ({result.path})",
                ("parameter", "MAE (m or rad)"), rows)  # fmt: skip
    return 0


def _command(args: argparse.Namespace) -> str:
    """The command that reproduces this run, every setting spelled out (stored in the weights)."""
    source = f"--data {shlex.quote(args.data)}" if args.data else f"--generate {args.generate}"
    words = [
        "grace train", shlex.quote(args.concept), source, f"--epochs {args.epochs}",
        f"--points {args.points}", f"--batch {args.batch}", f"--lr {args.lr:g}",
        f"--subsets {args.subsets}", f"--seed {args.seed}", f"--threads {args.threads}",
    ]  # fmt: skip
    if args.generate is not None:
        words.append(f"--noise {args.noise:g}")
    return " ".join(words + ["-o", shlex.quote(Path(args.output).name)])


def _generate(concept: str, n: int, seed: int, noise: float) -> list[Any]:
    """``n`` views of ``concept`` drawn with ``seed``, with a progress bar."""
    from grace_dsl.perception.views import generate_views

    with _bar(True) as bar:
        task = bar.add_task(f"views of {concept}", total=n)
        return generate_views(concept, n, seed, noise=noise,
                              progress=lambda k: bar.advance(task, k))  # fmt: skip


def _bar(enabled: bool) -> Any:
    from rich.console import Console
    from rich.progress import (
        BarColumn,
        MofNCompleteColumn,
        Progress,
        TextColumn,
        TimeElapsedColumn,
        TimeRemainingColumn,
    )

    return Progress(
        TextColumn("{task.description}"), BarColumn(), MofNCompleteColumn(),
        TimeElapsedColumn(), TimeRemainingColumn(),
        console=Console(stderr=True), transient=True, disable=not enabled,
    )  # fmt: skip

"""``eacc verify``: machine-check concepts over random parameter draws.

Thin: parse the arguments, show a progress bar over the concepts, print a table of failures (or
the whole report as JSON). Exit 0 when every check passes, 1 when one fails (or the sources do
not compile), 2 on a usage error such as an unknown concept.
"""

from __future__ import annotations

import argparse
import math
import sys
from collections.abc import Callable, Iterator
from contextlib import contextmanager
from typing import TYPE_CHECKING

from grace_dsl.cli.output import console, print_json, print_table, print_text
from grace_dsl.runtime.errors import ParameterError
from grace_dsl.runtime.gripper import Gripper
from grace_dsl.runtime.verify import VerifyReport, summarize, verifiable, verify_library

if TYPE_CHECKING:
    from grace_dsl.runtime.library import Library


def add_verify_arguments(p: argparse.ArgumentParser) -> None:
    p.add_argument("paths", nargs="*", help="default: the standard library")
    p.add_argument(
        "--concept",
        action="append",
        default=[],
        metavar="NAME",
        help="verify only this concept (repeatable; default: every concept)",
    )
    p.add_argument("--draws", type=_positive, default=200, help="valid draws per concept")
    p.add_argument("--seed", type=int, default=0, help="seed of the draws (default 0)")
    p.add_argument(
        "--gripper",
        default="panda",
        metavar="NAME|FILE",
        help="the hand: a shipped one (panda, topdown, pusher) or a .toml description file",
    )
    p.add_argument("--json", action="store_true", help="print the whole report as JSON")
    p.add_argument(
        "--scale",
        type=_scales,
        default=(1.0,),
        metavar="S[,S...]",
        help="multiply every length range by each factor, e.g. 0.3,2 (instances are made with "
        'ranges="valid"; default 1)',
    )


def _scales(text: str) -> tuple[float, ...]:
    """``0.3,2`` as (0.3, 2.0): finite factors > 0."""
    out = []
    for part in text.split(","):
        try:
            value = float(part)
        except ValueError:
            raise argparse.ArgumentTypeError(
                f"expected numbers such as 0.3,2, got {text!r}"
            ) from None
        if not (math.isfinite(value) and value > 0):
            raise argparse.ArgumentTypeError(f"a scale is a finite number > 0, got {part!r}")
        out.append(value)
    return tuple(dict.fromkeys(out))


def _positive(text: str) -> int:
    try:
        value = int(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"expected a whole number, got {text!r}") from None
    if value < 1:
        raise argparse.ArgumentTypeError(f"expected at least 1, got {value}")
    return value


def run_verify(args: argparse.Namespace, lib: Library) -> int:
    names = _chosen(lib, args.concept)
    if names is None:
        return 2
    try:
        hand = Gripper.load(args.gripper)
    except ParameterError as exc:
        sys.stderr.write(f"eacc verify: {exc}\n")
        return 2
    reports = []
    for scale in args.scale:
        with _progress() as progress:
            reports.append(
                verify_library(
                    lib,
                    names,
                    draws=args.draws,
                    seed=args.seed,
                    gripper=hand,
                    progress=progress,
                    scale=scale,
                )
            )
    if args.json:
        if len(reports) == 1:
            print_json(reports[0].to_json())
        else:
            print_json({"ok": all(r.ok for r in reports), "runs": [r.to_json() for r in reports]})
    else:
        for report in reports:
            _print_report(report)
    return 0 if all(r.ok for r in reports) else 1


def _chosen(lib: Library, wanted: list[str]) -> list[str] | None:
    """The concepts to verify, or None (after a message) when one is unknown or a primitive."""
    if not wanted:
        return verifiable(lib)
    for name in wanted:
        try:
            concept = lib[name]
        except KeyError as exc:
            sys.stderr.write(f"eacc verify: {exc}\n")
            return None
        if concept.entry["kind"] == "primitive":
            sys.stderr.write(f"eacc verify: {name} is a primitive: it has nothing to verify\n")
            return None
    return list(dict.fromkeys(wanted))


@contextmanager
def _progress() -> Iterator[Callable[[str, int, int], None] | None]:
    """A transient bar over the concepts on a terminal (stderr), nothing when piped."""
    err = console(stderr=True)
    if not err.is_terminal:
        yield None
        return
    from rich.progress import BarColumn, MofNCompleteColumn, Progress, TimeElapsedColumn

    columns = (BarColumn(), MofNCompleteColumn(), TimeElapsedColumn())
    with Progress("{task.description}", *columns, console=err, transient=True) as bar:
        task = bar.add_task("verifying", total=None)

        def progress(name: str, done: int, total: int) -> None:
            bar.update(task, total=total, completed=done, description=f"verifying {name}")

        yield progress


def _print_report(report: VerifyReport) -> None:
    at = f", every length x{report.scale:g}" if report.scale != 1.0 else ""
    print_table(
        f"{len(report.concepts)} concepts, {report.draws} draws each (seed {report.seed}, "
        f"{report.gripper} gripper{at})",
        ["concept", "draws", "acceptance", "checks", "failures", "note"],
        [
            [
                c.concept,
                str(c.draws),
                f"{c.draws / c.attempts:.0%}" if c.attempts else "-",
                str(sum(c.evaluated.values())),
                str(len(c.failures)),
                c.note,
            ]
            for c in report.concepts
        ],
    )
    if report.ok:
        print_text("every check passed", style="green")
        return
    rows = []
    for f, n in sorted(summarize(report.failures), key=lambda x: (x[0].concept, x[0].check)):
        unit = f" {f.unit}" if f.unit else ""
        params = ", ".join(f"{k}={v}" for k, v in f.params.items())
        rows.append(
            [
                f.concept,
                f.check,
                f.member,
                params,
                f"{f.value:.4g}{unit}",
                f"{f.limit:g}{unit}",
                str(n),
            ]
        )
    print_table(
        "failures (the worst draw of each; --json lists every failing draw)",
        ["concept", "check", "member", "params", "value", "limit", "draws"],
        rows,
    )
    bad = sum(not c.ok for c in report.concepts)
    print_text(f"{len(report.failures)} failing draws in {bad} concepts", style="red")

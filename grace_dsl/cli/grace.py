"""``grace``: the GRACE pipeline's command line. For now: ``grace demo``."""

from __future__ import annotations

import argparse
from collections.abc import Sequence

import numpy as np

from grace_dsl.cli.eacc import main as eacc_main
from grace_dsl.cli.output import print_text


def main(argv: Sequence[str] | None = None) -> int:
    parser = argparse.ArgumentParser(prog="grace", description="The GRACE pipeline.")
    sub = parser.add_subparsers(dest="command")
    sub.add_parser("demo", help="compile the standard library and show what a concept computes")
    args = parser.parse_args(argv)
    if args.command != "demo":
        parser.print_help()
        return 2
    return demo()


def demo() -> int:
    """Compile the standard library, list it, and instantiate the paper's sunken door."""
    status = eacc_main(["list"])
    if status:
        return status
    import grace_dsl as eac

    door = eac.load_library()["SunkenDoor"].instantiate(joints={"hinge": 0.4})
    grasp = door.grasp("handle.pull", theta=0.0)
    np.set_printoptions(precision=4, suppress=True)
    print_text("\nSunkenDoor with its hinge at 0.4 rad: grasp `handle.pull` at theta = 0")
    print_text(str(grasp))
    print_text(f"force to open: {door.force('open', grasp)}")
    path = door.follow("open", grasp, to=1.2, steps=5)
    print_text(f"gripper positions while opening to 1.2 rad:\n{path[:, :3, 3]}")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())

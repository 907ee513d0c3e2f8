"""``grace``: the GRACE pipeline's command line: ``grace demo``, ``grace plan``, ``grace bench``."""

from __future__ import annotations

import argparse
from collections.abc import Sequence
from dataclasses import replace
from pathlib import Path
from typing import Any

import numpy as np

from grace_dsl.cli.eacc import main as eacc_main
from grace_dsl.cli.output import error, print_text
from grace_dsl.runtime.errors import GraceError

#: The subcommands other than ``demo``: (name, module, function adding its arguments, function
#: running it, help). Each lives in its own module, imported only when ``grace`` starts.
COMMANDS = (
    (
        "plan",
        "plan_cmd",
        "add_plan_arguments",
        "run_plan",
        "plan an action for the Panda and show it",
    ),
    (
        "bench",
        "bench_cmd",
        "add_bench_arguments",
        "run_bench",
        "open and close articulated objects in simulation; a table",
    ),
    (
        "parse",
        "parse_cmd",
        "add_parse_arguments",
        "run_parse",
        "an instruction in a scene -> its plan",
    ),
    (
        "run",
        "run_cmd",
        "add_run_arguments",
        "run_run",
        "carry out an instruction in a simulated scene",
    ),
    (
        "data",
        "data_cmd",
        "add_data_arguments",
        "run_data",
        "synthetic views for perception (data gen)",
    ),
    (
        "estimate",
        "estimate_cmd",
        "add_estimate_arguments",
        "run_estimate",
        "fit a concept to a partial cloud",
    ),
)


def main(argv: Sequence[str] | None = None) -> int:
    import importlib

    parser = argparse.ArgumentParser(prog="grace", description="The GRACE pipeline.")
    sub = parser.add_subparsers(dest="command")
    demo_parser = sub.add_parser(
        "demo", help="compile the standard library and show what a concept computes"
    )
    demo_parser.add_argument(
        "-o", "--output", default="out/demo", help="where the picture and viewer page go"
    )
    runners = {}
    for name, module_name, add, run, help_text in COMMANDS:
        module = importlib.import_module(f"grace_dsl.cli.{module_name}")
        getattr(module, add)(sub.add_parser(name, help=help_text))
        runners[name] = getattr(module, run)
    from grace_dsl.cli.train_cmd import register as register_train

    register_train(sub)  # grace train: its handler rides on the parsed arguments
    args = parser.parse_args(argv)
    if hasattr(args, "handler"):
        return int(args.handler(args))
    if args.command in runners:
        return int(runners[args.command](args))
    if args.command != "demo":
        parser.print_help()
        return 2
    try:
        return demo(Path(args.output), episodes=True)
    except GraceError as exc:  # an output directory that cannot be written, say
        error(str(exc))
        return 1


def demo(output: Path, episodes: bool = False) -> int:
    """Compile the standard library, list it, and put the paper's sunken door through its paces:
    a grasp, the force and path that open it, the manipulation functions a Panda hand and a
    hand that cannot close would use, and a picture and 3D page of it all. With ``episodes``,
    then simulate the demo's episodes (``demo_episodes``)."""
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
    panda = replace(eac.Gripper.panda(), name="the Panda hand")
    no_fingers = replace(panda, name="a hand that cannot close", can_close=False)
    for action in ("open", "close"):
        for hand in (panda, no_fingers):
            _print_options(door, action, hand)
    _pictures(door, output)
    if episodes:
        demo_episodes(output / "bench")
    return 0


def demo_episodes(output: Path, fn: Any = None) -> dict[str, Any]:
    """A drawer and a door opened and closed by the flying Panda hand, one episode each
    (``bench_cmd.demo_jobs``), the table printed and the report written to ``output``; ``fn``
    replaces the simulated episode. Returns the run's summary."""
    from grace_dsl.cli.bench_cmd import bench, demo_jobs

    jobs = demo_jobs()
    result = bench(jobs, output, fn=fn, settings=None)
    print_text("\nsimulated episodes (flying Panda hand, seed 0):\n" + result.table)
    print_text(f"report: {output}")
    if fn is None:  # pictures and a replay of the real episode (another fn has no world)
        config, seed = jobs[0]
        demo_replay(config, seed, output / "replay")
    if fn is None:
        demo_arm(output / "arm.json")
    return result.summary


def demo_arm(path: Path) -> None:
    """One episode of the whole Panda on a base beside a drawer, executing the robot layer's
    planned trajectory in MuJoCo (``sim.arm_episode``); its record printed and written."""
    import json

    from grace_dsl.cli.files import atomic_write
    from grace_dsl.sim.arm_episode import demo_arm_episode

    record = demo_arm_episode()
    verdict = "success" if record.strict else f"failed ({record.reason}: {record.detail})"
    print_text(
        f"\narm episode (the Panda on a base, {record.config.concept} {record.config.task}, "
        f"seed {record.seed}): {verdict}; joint {record.q_initial:.3f} -> {record.q_final:.3f}"
    )
    atomic_write(path, json.dumps(record.to_json(), indent=1))


def demo_replay(config: Any, seed: int, output: Path) -> dict[str, Path]:
    """One episode run again with its motion traced: before and after pictures from its camera
    and the HTML viewer page replaying it. Returns the files written."""
    from grace_dsl.cli.replay import replay_html
    from grace_dsl.sim.episode import Z_UP
    from grace_dsl.sim.replay import ReplayError, first_qpos, render_world, replay

    record, world = replay(config, seed)
    name = f"{config.concept}-{config.task}"
    if world is None:
        print_text(f"replay skipped: the hand never moved ({record.reason}: {record.detail})")
        return {}
    files = {"html": replay_html(world, record.joint, name, Z_UP, output / f"{name}.html")}
    try:
        before = render_world(
            world, record.camera, output / f"{name}-before.png", first_qpos(world)
        )
        files["before"] = before
        files["after"] = render_world(world, record.camera, output / f"{name}-after.png")
    except ReplayError as exc:  # no OpenGL here: the page is still written
        print_text(f"pictures skipped: {exc}")
    for kind, path in files.items():
        print_text(f"{kind}: {path}")
    return files


def _print_options(inst: Any, action: str, hand: Any) -> None:
    """The manipulation functions of ``action`` for ``hand``, best first."""
    lines = [f"\nto {action} with {hand.name}:"]
    for o in inst.rank(action, hand):
        verdict = "yes" if o.feasible else "no: " + "; ".join(o.reasons)
        lines.append(f"  {o.grasp:<14} by {o.mode:<6} {verdict}")
    print_text("\n".join(lines))


def _pictures(inst: Any, output: Path) -> None:
    """A PNG (MuJoCo, offscreen) and a self-contained HTML viewer of the door with its grasp
    frames, forces and hinge axis; the PNG is skipped with a note where no OpenGL exists."""
    from grace_dsl.cli.files import atomic_write, staged
    from grace_dsl.render.html import scene_html
    from grace_dsl.render.png import RenderError
    from grace_dsl.render.scene import describe

    scene = describe(inst)
    html = atomic_write(output / "SunkenDoor.html", scene_html(scene, "hinge = 0.4 rad")).path
    print_text(f"\n3D viewer (open in a browser): {html}")
    try:
        from grace_dsl.export.model import build_model
        from grace_dsl.render.png import write_png

        model, png = build_model(inst), output / "SunkenDoor.png"
        staged(png, lambda p: write_png(scene, p, 800, 600, model))
        print_text(f"picture: {png}")
    except (RenderError, ImportError) as exc:
        print_text(f"picture skipped: {exc}")


if __name__ == "__main__":
    raise SystemExit(main())

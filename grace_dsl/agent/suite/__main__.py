"""``python -m grace_dsl.agent.suite``: the offline parser's accuracy on the task suite."""

from __future__ import annotations

import sys


def main() -> int:
    import grace_dsl as eac
    from grace_dsl.agent.offline import OfflineParser
    from grace_dsl.agent.suite import load_suite, parse_accuracy, shipped_scene_specs

    lib = eac.load_library()
    tasks = load_suite()
    result = parse_accuracy(OfflineParser(lib).parse, shipped_scene_specs(lib), tasks)
    steps = sum(len(t.steps) for t in tasks)
    print(f"{len(tasks)} instructions, {steps} steps, over {len(shipped_scene_specs(lib))} scenes")
    print(result.table())
    return 0 if result.accuracy >= 0.95 else 1


if __name__ == "__main__":
    sys.exit(main())

"""`make bench [SUITE...]`: speed, memory and accuracy figures (recorded in docs/benchmarks.md).

    PYTHONPATH=src:. python -m bench [speed] [memory] [intel] [office] [matcher] [longrun] [accuracy] [messages]
    [soak]   (default: all)

speed: one filter step for N in {20, 50, 100}, 60 and 360 beams, 10 m and 40 m maps.
memory: peak RSS for N in {30, 100, 300} on the Intel log and a 250 m building, tiles and dense.
intel, office: the presets' accuracy (real and slam on Intel, burger and slam on the office; bench.modes).
accuracy: config/real.yaml over the whole development set through the offline tool.
matcher: the scan matcher alone against reference poses.
longrun: 30 simulated minutes of the office loop, time and memory sampled.
messages: the node's large messages (a 4000 x 4000 map, a 108 000-pose path), genpy against packed.
soak: the live node (slam.launch) for 30 simulated minutes under every fault class at once.
Each suite is a module of this folder, also runnable alone (`python -m bench.speed`).
"""
from __future__ import annotations

import argparse
import importlib
import sys

from fastslam.cli import closed_output_ends_quietly

SUITES = {"speed": ("bench.speed", []), "memory": ("bench.memory", ["--dense"]), "intel": ("bench.modes", []),
          "office": ("bench.modes", ["--office"]), "matcher": ("bench.matcher", None),
          "longrun": ("bench.longrun", []), "accuracy": ("bench.accuracy", []),
          "messages": ("bench.messages", []), "soak": ("bench.soak", [])}


@closed_output_ends_quietly
def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(prog="make bench", description=__doc__.splitlines()[0])
    parser.add_argument("suites", nargs="*", default=list(SUITES), choices=list(SUITES), metavar="SUITE",
                        help=f"{', '.join(SUITES)} (default: all)")
    for suite in parser.parse_args(argv).suites:
        print(f"== {suite}", flush=True)
        module, args = SUITES[suite]
        run = importlib.import_module(module).main
        for suite_args in ([["intel"], ["office"]] if args is None else [args]):
            run(suite_args)
    return 0


if __name__ == "__main__":
    sys.exit(main())

"""How many URDFs of the installed example-robot-data load: before/after the inertia policy.

Every robot of :func:`youbot_opt.robot.catalogue.example_robots` (one per URDF file,
69 in example-robot-data 6.0.0) is loaded with a fixed base by default and, if
refused, with ``strict=False`` (:func:`youbot_opt.cli.robots.survey`). "Before" is
the policy of issue 6 (any physically implausible inertia refused), counted as
the robots that load by default without an implausible-inertia warning; the
baseline of the same run is Pinocchio's own loader (no checks). Prints the
counts and each refusal with its rule; ``--json FILE`` writes the rows.

    python benchmarks/bench_robot_zoo_loading.py [--json FILE]
"""

from __future__ import annotations

import argparse
import json
import sys
import time
from dataclasses import asdict

import pinocchio as pin

from youbot_opt.cli.robots import survey
from youbot_opt.robot.catalogue import example_robot_data_dir, example_robots


def _pinocchio_loads(path: str) -> bool:
    try:
        pin.buildModelFromUrdf(path)
    except (ValueError, RuntimeError):
        return False
    return True


def main() -> int:
    """Survey every example-robot-data URDF and print the counts."""
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--json", default=None, help="write the rows to this file")
    args = parser.parse_args()
    zoo = example_robots()
    print(f"example-robot-data at {example_robot_data_dir()}: {len(zoo)} URDF files")
    tic = time.perf_counter()
    rows = []
    for i, name in enumerate(zoo, 1):
        print(f"[{i}/{len(zoo)}] {name}", file=sys.stderr, flush=True)
        rows.append(survey(name))
    elapsed = time.perf_counter() - tic
    pinocchio = sum(_pinocchio_loads(str(p)) for p in zoo.values())
    before = sum(r.status == "default" and r.warnings == 0 for r in rows)
    default = sum(r.status == "default" for r in rows)
    lenient = default + sum(r.status == "lenient" for r in rows)
    print(f"Pinocchio's own loader (baseline, no checks): {pinocchio}/{len(zoo)}")
    print(f"before (every implausible inertia refused):   {before}/{len(zoo)}")
    print(f"after, default (strict=True):                 {default}/{len(zoo)}")
    print(f"after, lenient (strict=False / --lenient):    {lenient}/{len(zoo)}")
    print(f"surveyed in {elapsed:.1f} s")
    for r in rows:
        if r.status != "default":
            print(f"  {r.name:<36} {r.status:<8} {r.reason}")
    if args.json:
        with open(args.json, "w", encoding="utf-8") as f:
            json.dump([asdict(r) for r in rows], f, indent=1)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())

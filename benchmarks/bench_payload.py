"""Payload mass sweep (issue 30, item 1): best T and W of study 1 against the mass at the tip.

Run ``python benchmarks/bench_payload.py [--quick] [--masses 0,0.1,...] [--knots 30]
[--starts 8] [--method hermite_simpson] [--figure DIR] [--json FILE]``.

The study-1 motion (beta = 0.5, data-sheet bounds) on the youBot arm carrying
a point mass at ``gripper_tip``, one multistart per mass
(:func:`youbot_opt.trajopt.payload_sweep.payload_sweep`, the straight start and
``--starts`` spline starts, serial). Prints the table (mass, T, W, f,
converged starts) and, with ``--figure DIR``, writes ``payload_sweep.png`` (T
and W against mass).
"""

from __future__ import annotations

import argparse
import json
import time
from pathlib import Path

from youbot_opt.reproduction.study1 import study1_problem
from youbot_opt.robot.load import load_model
from youbot_opt.sweeps.options import SweepOptions
from youbot_opt.trajopt.payload_sweep import PayloadSweep, payload_sweep


def _figure(sweep: PayloadSweep, folder: Path) -> Path:
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig, (ax_t, ax_w) = plt.subplots(1, 2, figsize=(9, 3.5), constrained_layout=True)
    ax_t.plot(sweep.masses, sweep.durations, "o-")
    ax_t.set(xlabel="payload mass [kg]", ylabel="T [s]", title="duration")
    ax_w.plot(sweep.masses, sweep.works, "o-", color="C1")
    ax_w.set(xlabel="payload mass [kg]", ylabel="W [N$^2$ m$^2$ s]", title="work")
    folder.mkdir(parents=True, exist_ok=True)
    path = folder / "payload_sweep.png"
    fig.savefig(path, dpi=120)
    plt.close(fig)
    return path


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--quick", action="store_true", help="3 masses, 12 knots, 1 start")
    parser.add_argument("--masses", default="0,0.1,0.2,0.3,0.4,0.5,0.6,0.8,1.0")
    parser.add_argument("--knots", type=int, default=30)
    parser.add_argument("--starts", type=int, default=8)
    parser.add_argument("--method", default="hermite_simpson")
    parser.add_argument("--figure", type=Path, default=None)
    parser.add_argument("--json", type=Path, default=None)
    args = parser.parse_args()
    masses = [0.0, 0.25, 0.5] if args.quick else [float(m) for m in args.masses.split(",")]
    knots, starts = (12, 1) if args.quick else (args.knots, args.starts)
    problem = study1_problem(knots, robot=load_model("youbot"))
    tic = time.perf_counter()
    sweep = payload_sweep(
        problem, masses, method=args.method, n_starts=starts, sweep=SweepOptions(executor="serial")
    )
    elapsed = time.perf_counter() - tic
    print(f"study 1, {knots} knots, {args.method}, beta 0.5, {starts} + 1 starts per mass")
    print(sweep.table())
    print(f"{elapsed:.1f} s")
    if args.figure is not None:
        print(f"figure: {_figure(sweep, args.figure)}")
    if args.json is not None:
        rows = [
            {"mass_kg": p.mass, "duration_s": p.duration, "work": p.work, "objective": p.objective,
             "converged": p.n_converged, "starts": p.n_starts}
            for p in sweep.points
        ]  # fmt: skip
        args.json.write_text(json.dumps({"knots": knots, "method": args.method, "rows": rows}))


if __name__ == "__main__":
    main()

"""What a solve's figures cost (issue 27, item 2 "outputs off the critical path").

Run ``python benchmarks/bench_figures.py [--repeats N] [--json]``.

On the ur5 solve of ``bench_wait.py`` (``youbot-opt solve --robot ur5 --start 0
-1.2 1 -0.5 0.3 0 --goal 0.8 -0.6 0.4 -1.2 -0.3 0.5``, refinement on):

* **per figure**, in this process, fresh figures, the least of ``--repeats``:
  making the figure, saving it as the command does (constrained layout, dpi
  120), and saving it without a layout engine (the difference: the layout's
  share);
* **outputs**, in ``--repeats`` fresh interpreters each running the command:
  the wall of ``write_solve_outputs`` (result, replay, figures, summary), of
  which the caller's ``Drawing(...)`` (forking; before issue 27 item 2 also
  importing matplotlib) and ``Drawing.wait()`` (waiting for the drawing
  processes), and the command's wall; medians.

Wall times on a shared machine are inflated by other processes (the load
average is printed): compare runs made at the same load.
"""

from __future__ import annotations

import argparse
import importlib
import io
import json
import os
import statistics
import subprocess
import sys
import tempfile
import time
from pathlib import Path
from typing import Any

ARGV = ["solve", "--robot", "ur5", "--start", "0", "-1.2", "1", "-0.5", "0.3", "0",
        "--goal", "0.8", "-0.6", "0.4", "-1.2", "-0.3", "0.5"]  # fmt: skip

_CHILD = r"""
import contextlib, io, json, sys, time
t0 = time.perf_counter()
import youbot_opt.cli.drawing as dr
import youbot_opt.cli.solve as solve
phase = {"outputs": 0.0, "drawing_init": 0.0, "drawing_wait": 0.0}
def timing(name, f):
    def g(*a, **k):
        t = time.perf_counter()
        try:
            return f(*a, **k)
        finally:
            phase[name] += time.perf_counter() - t
    return g
dr.Drawing.__init__ = timing("drawing_init", dr.Drawing.__init__)
dr.Drawing.wait = timing("drawing_wait", dr.Drawing.wait)
solve.write_solve_outputs = timing("outputs", solve.write_solve_outputs)
from youbot_opt.cli import main
with contextlib.redirect_stdout(io.StringIO()), contextlib.redirect_stderr(io.StringIO()):
    main(json.loads(sys.argv[1]))
phase["command"] = time.perf_counter() - t0
print(json.dumps(phase))
"""


def _jobs(folder: Path) -> list[Any]:
    """Run the solve here, figures drawn here; return its figure jobs."""
    import youbot_opt.cli.drawing as drawing
    from youbot_opt.cli import main

    jobs = []
    draw, forks = drawing.draw_job, drawing._forks

    def keep(where: Path, job: Any) -> Any:
        jobs.append(job)
        return draw(where, job)

    drawing.draw_job, drawing._forks = keep, lambda: False  # drawn here: seen here
    try:
        main([*ARGV, "--out", str(folder), "--quiet", "--json"])
    finally:
        drawing.draw_job, drawing._forks = draw, forks
    return jobs


def per_figure(repeats: int, folder: Path) -> dict[str, dict[str, float]]:
    """Make / save (as shipped) / save without a layout engine, per figure, seconds."""
    import contextlib

    from matplotlib.backends.backend_agg import FigureCanvasAgg

    with contextlib.redirect_stdout(io.StringIO()), contextlib.redirect_stderr(io.StringIO()):
        jobs = _jobs(folder)
    out = {}
    for job in jobs:
        module, _, name = job.make.partition(":")
        make = getattr(importlib.import_module(module), name)
        best = {"make": 1e9, "save": 1e9, "save_no_layout": 1e9}
        for _ in range(repeats):
            for key in ("save", "save_no_layout"):
                tic = time.perf_counter()
                fig = make(*job.args, **dict(job.kwargs))
                FigureCanvasAgg(fig)
                best["make"] = min(best["make"], time.perf_counter() - tic)
                if key == "save_no_layout":
                    fig.set_layout_engine("none")
                tic = time.perf_counter()
                fig.savefig(io.BytesIO(), format="png", dpi=job.dpi)
                best[key] = min(best[key], time.perf_counter() - tic)
        out[job.name] = best
    return out


def outputs(repeats: int, work: Path) -> dict[str, float]:
    """Medians over fresh interpreters of the command's phases, seconds."""
    env = {**os.environ, "PYTHONPATH": str(Path(__file__).parents[1] / "src")}
    runs = []
    for k in range(repeats + 1):  # the first warms the caches, not counted
        argv = json.dumps([*ARGV, "--out", str(work / f"run{k}")])
        done = subprocess.run(
            [sys.executable, "-c", _CHILD, argv], env=env, capture_output=True, text=True
        )
        if done.returncode != 0:
            raise RuntimeError(done.stderr)
        if k:
            runs.append(json.loads(done.stdout.splitlines()[-1]))
    return {key: statistics.median(r[key] for r in runs) for key in runs[0]}


def main(argv: list[str] | None = None) -> int:
    """Run the benchmark; print a table (or ``--json``)."""
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--repeats", type=int, default=3)
    parser.add_argument("--json", action="store_true")
    args = parser.parse_args(argv)
    with tempfile.TemporaryDirectory() as tmp:
        figures = per_figure(args.repeats, Path(tmp) / "here")
        phases = outputs(args.repeats, Path(tmp))
    doc = {"load_average": os.getloadavg(), "figures": figures, "outputs": phases}
    if args.json:
        print(json.dumps(doc, indent=2))
        return 0
    print(f"load average {doc['load_average'][0]:.2f}")
    print(f"{'figure':18s} {'make':>6s} {'save':>6s} {'no layout':>9s}")
    for name, t in figures.items():
        print(f"{name:18s} {t['make']:6.3f} {t['save']:6.3f} {t['save_no_layout']:9.3f}")
    total = {k: sum(t[k] for t in figures.values()) for k in ("make", "save", "save_no_layout")}
    print(f"{'total':18s} {total['make']:6.3f} {total['save']:6.3f} {total['save_no_layout']:9.3f}")
    print(f"medians of {args.repeats} fresh runs: " + ", ".join(
        f"{k} {v:.3f} s" for k, v in phases.items()))  # fmt: skip
    return 0


if __name__ == "__main__":
    raise SystemExit(main())

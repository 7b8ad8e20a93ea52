"""Time the sweeps on the local process pool and on a local Dask cluster, and the driver's cost.

Run ``python benchmarks/bench_sweeps.py [--quick] [--items N] [--json]``. In one
run, so the ratios compare like with like (issue #15):

* the 200-start trajectory multistart (study 1, beta = 0.5, 50 knots) on the
  local pool of 2 worker processes (baseline) and on a 2-worker Dask
  ``LocalCluster`` (worker processes, 1 thread each, on 127.0.0.1); target:
  Dask overhead <= 15 %; the per-start results must be identical;
* the 1000-start IK-path multistart (example B, AL) on the same two;
* the driver's cost per item: trivial items (``math.sqrt``) through
  :func:`~youbot_opt.sweeps.resume.run_resumable` in this process, without and
  with the on-disk store, and on the Dask cluster (batches of 64); goal
  >= 2000 items/s, recorded;
* an ``--items``-item trivial sweep (default 10^4, the issue's 10^5 with
  ``--items 100000``) through the real store: driver RSS at every tenth of
  the run (flat = bounded growth), wall time, and the time to resume it.

``--quick``: 40 trajectory starts, 200 IK starts, 2000 store items. Wall times
on a shared 2-core machine are noisy (20-100 % between runs when other
processes compete): each sweep runs ``--repeat`` times (default 3) on both
executors, interleaved, and the fastest run of each counts.
"""

from __future__ import annotations

import argparse
import json
import math
import tempfile
import time
from pathlib import Path

from youbot_opt.ikpath.examples import example_problem
from youbot_opt.ikpath.multistart import run_multistart as ik_multistart
from youbot_opt.reproduction.study1 import study1_problem
from youbot_opt.sweeps.options import SweepOptions
from youbot_opt.sweeps.pool import Task
from youbot_opt.sweeps.resume import run_resumable
from youbot_opt.sweeps.store import SweepStore
from youbot_opt.trajopt.multistart import run_multistart
from youbot_opt.trajopt.solver import TrajOptSolver

TARGET_OVERHEAD = 0.15  # Dask wall / pool wall - 1, at most
GOAL_ITEMS_PER_S = 2000.0  # driver cost per item, goal


def _rss_mb() -> float:
    for line in Path("/proc/self/status").read_text().splitlines():
        if line.startswith("VmRSS:"):
            return int(line.split()[1]) / 1024.0
    return math.nan


def _timed(fn):  # type: ignore[no-untyped-def]
    tic = time.perf_counter()
    out = fn()
    return out, time.perf_counter() - tic


def _trivial(n: int, out: Path | None, executor, samples: list | None = None):  # type: ignore[no-untyped-def]
    store = None
    if out is not None:
        store = SweepStore(
            out,
            kind="bench",
            params={"n": n},
            save=lambda v, p: p.write_text(repr(v)),
            load=lambda p: float(p.read_text()),
            suffix=".txt",
        )
    tasks = [Task(key=f"i{i:06d}", fn=math.sqrt, args=(float(i),)) for i in range(n)]
    step = max(1, n // 10)

    def on_final(key: str, value: float, done: int) -> None:
        if samples is not None and done % step == 0:
            samples.append(round(_rss_mb(), 1))

    got = run_resumable(
        tasks,
        store=store,
        options=SweepOptions(executor=executor, batch_size=64),
        load=lambda key: store.load(key),  # type: ignore[union-attr]
        convert=lambda o: o.value,
        payload=lambda key, v: (v, {"v": v}),
        on_final=on_final,
    )
    return got


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--quick", action="store_true", help="smaller sweeps")
    parser.add_argument("--items", type=int, default=None, help="store sweep size (1e4)")
    parser.add_argument("--json", action="store_true", help="print the figures as JSON too")
    parser.add_argument(
        "--repeat",
        type=int,
        default=3,
        help="runs of each sweep on each executor, interleaved; the fastest counts (default 3)",
    )
    parser.add_argument(
        "--skip-ik", action="store_true", help="leave out the IK sweeps (the longest part)"
    )
    args = parser.parse_args()
    n_traj, n_ik = (40, 200) if args.quick else (200, 1000)
    n_store = args.items or (2000 if args.quick else 10_000)
    from distributed import Client, LocalCluster

    rows: dict[str, float] = {}
    solver = TrajOptSolver(study1_problem(50))
    prob = example_problem("B")
    with (
        LocalCluster(
            n_workers=2, threads_per_worker=1, processes=True, host="127.0.0.1",
            dashboard_address=None,
        ) as cluster,
        Client(cluster) as client,
    ):  # fmt: skip
        client.wait_for_workers(2)
        # warm both: imports and the first solver build happen outside the timings
        run_multistart(solver, 2, seed=99, sweep=SweepOptions(executor=client))
        ik_multistart(prob, n_starts=4, seed=99, sweep=SweepOptions(executor=client))
        for name, run in (
            ("traj", lambda ex: run_multistart(solver, n_traj, beta=0.5, seed=0,
                                               sweep=SweepOptions(executor=ex, workers=2))),
            ("ik", lambda ex: ik_multistart(prob, n_starts=n_ik, seed=0,
                                            sweep=SweepOptions(executor=ex, workers=2))),
        ):  # fmt: skip
            if name == "ik" and args.skip_ik:
                continue
            t_pool = t_dask = math.inf
            for _ in range(args.repeat):  # interleaved: both see the same machine load
                pool, t = _timed(lambda run=run: run("process"))
                t_pool = min(t_pool, t)
                dask, t = _timed(lambda run=run: run(client))
                t_dask = min(t_dask, t)
            if name == "traj":
                same = [s.objective for s in pool.starts] == [s.objective for s in dask.starts]
            else:
                same = [r.objective for r in pool.results] == [r.objective for r in dask.results]
            rows[f"{name}_pool_s"], rows[f"{name}_dask_s"] = t_pool, t_dask
            rows[f"{name}_overhead"] = t_dask / t_pool - 1.0
            rows[f"{name}_identical"] = float(same)

        n_driver = 20_000 if not args.quick else 5000
        _, t = _timed(lambda: _trivial(n_driver, None, "serial"))
        rows["driver_items_per_s_nostore"] = n_driver / t
        _, t = _timed(lambda: _trivial(n_driver, None, client))
        rows["dask_items_per_s_nostore"] = n_driver / t
        with tempfile.TemporaryDirectory() as tmp:
            n = min(n_driver, 5000)
            _, t = _timed(lambda: _trivial(n, Path(tmp) / "s", "serial"))
            rows["driver_items_per_s_store"] = n / t

    with tempfile.TemporaryDirectory() as tmp:
        samples: list[float] = []
        rss0 = _rss_mb()
        _, t_run = _timed(lambda: _trivial(n_store, Path(tmp) / "big", "serial", samples))
        _, t_resume = _timed(lambda: _trivial(n_store, Path(tmp) / "big", "serial"))
        rows["store_items"] = n_store
        rows["store_run_s"], rows["store_resume_s"] = t_run, t_resume
        rows["store_rss_growth_mb"] = (samples[-1] if samples else rss0) - rss0

    print(f"{'sweep':<34}{'local pool [s]':>16}{'Dask [s]':>12}{'overhead':>10}{'identical':>10}")
    for name, label in (
        ("traj", f"trajectory, {n_traj} starts"),
        ("ik", f"IK path, {n_ik} starts"),
    ):
        if f"{name}_pool_s" not in rows:
            continue
        ok = "yes" if rows[f"{name}_identical"] else "NO"
        print(
            f"{label:<34}{rows[f'{name}_pool_s']:>16.2f}{rows[f'{name}_dask_s']:>12.2f}"
            f"{rows[f'{name}_overhead']:>+10.0%}{ok:>10}"
        )
    print(f"target: Dask overhead <= {TARGET_OVERHEAD:.0%}")
    print(
        f"driver cost: {rows['driver_items_per_s_nostore']:.0f} items/s in-process without a "
        f"store, {rows['driver_items_per_s_store']:.0f} items/s with the store, "
        f"{rows['dask_items_per_s_nostore']:.0f} items/s on Dask (goal >= {GOAL_ITEMS_PER_S:.0f})"
    )
    print(
        f"store sweep of {n_store} trivial items: {rows['store_run_s']:.1f} s, resume "
        f"{rows['store_resume_s']:.1f} s, driver RSS at each tenth {samples} MB "
        f"(growth {rows['store_rss_growth_mb']:.1f} MB)"
    )
    if args.json:
        print(json.dumps(rows, indent=1))


if __name__ == "__main__":
    main()

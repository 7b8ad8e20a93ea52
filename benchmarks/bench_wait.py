"""The user's wait (issue 27, item 6): the command line as a user runs it, wall time.

Run ``python benchmarks/bench_wait.py [--quick] [--repeats N] [--reference-starts K]
[--robots ur5 panda xarm7] [--compare-jobs] [--keep DIR] [--json]``.

Each case runs ``youbot-opt`` in a fresh interpreter (``python -m youbot_opt``),
with default settings (refinement on), and times the whole command: start-up,
loading, build, every refinement round, the certificate, the printed report and
the run folder, until the command returns (and, warm, the command's CPU time:
less inflated by other processes than its wall time). Cases:

* **solve, ur5**: ``youbot-opt solve --robot ur5 --start 0 -1.2 1 -0.5 0.3 0
  --goal 0.8 -0.6 0.4 -1.2 -0.3 0.5 --out DIR`` (the motion of
  ``bench_refine.py``);
* **solve, panda**: ``--robot panda --lock panda_finger_joint1=0.02`` (the
  fingers locked, as the finger note advises), start and goal at 35 % and 65 %
  of each arm joint's range (as ``bench_first_solve.py``);
* **solve, xarm7**: a vendor arm, UFACTORY's own xArm7 description as
  example-robot-data ships it (``xarm_description``), start and goal as panda's;
* each **cold** (``YOUBOT_OPT_CACHE`` a fresh empty folder: nothing compiled,
  no sphere fits) and **warm** (the same cache again, after the background
  compiles of the cold run have finished: what every later run pays); ``bg``
  is how long the cold run's background compile went on after it returned
  (its kernels compiled as many at a time as there are idle cores); with
  ``--compare-jobs`` a second cold run compiles one kernel at a time
  (``YOUBOT_OPT_COMPILE_JOBS=1``: one at a time, as before this batch), for the
  before/after of the time to compiled code;
* **ikpath, ur5**: ``youbot-opt ikpath --robot ur5 --target X Y Z ...`` with 4
  and 6 position targets (the tool0 positions of in-limit configurations drawn
  with ``numpy.random.default_rng(2026)``, limits clipped to ``[-pi, pi]``),
  default settings, warm: wall time to the best path and its ``E``; with
  ``--reference-starts K`` (K > 0) also ``--starts K`` for the best known ``E``
  to compare with (slow: minutes for K = 1000).

A plan counts only when certified and its run folder holds ``summary.json``
(``--keep DIR`` keeps the run folders; the table names each warm run's).
Each time is also printed as a ratio of its target (1.00 = on target; the
vendor arm's targets are twice ur5's and panda's).
The machine's load average is printed: wall times on a shared machine are
inflated by other processes. ``--quick``: one repeat, no reference starts.
The runs cache bytecode as an installed package does: the package is compiled
first (``compileall``) and ``PYTHONDONTWRITEBYTECODE`` is left out of their
environment (a machine that sets it would otherwise have every run compile the
package's modules from source, 0.2-0.25 s, which a user's install does not pay);
``--no-bytecode`` keeps the environment as it is.
Targets (issue 27, 2 cores): warm <= 1.5 s, cold <= 5 s for ur5 and panda; the
IK path's best known E by default in <= 10 s.
"""

from __future__ import annotations

import argparse
import json
import os
import resource
import statistics
import subprocess
import sys
import tempfile
import time
from pathlib import Path
from typing import Any

import numpy as np

UR5 = (["0", "-1.2", "1", "-0.5", "0.3", "0"], ["0.8", "-0.6", "0.4", "-1.2", "-0.3", "0.5"])
PANDA_LOCK = ["--lock", "panda_finger_joint1=0.02"]
TARGETS = {"warm": 1.5, "cold": 5.0, "ikpath": 10.0}  # [s] wall, issue 27
VENDOR = {"xarm7"}  # vendor arms: targets 2x (issue 27)
ROBOTS = ("ur5", "panda", "xarm7")


def _target(robot: str, kind: str) -> float:
    return TARGETS[kind] * (2.0 if robot in VENDOR else 1.0)


def start_goal(name: str) -> tuple[list[str], list[str]]:
    """Start and goal at 35 % and 65 % of each joint's range (panda's fingers locked)."""
    import warnings

    from youbot_opt.robot.load import load_model

    locks = {"panda_finger_joint1": 0.02} if name == "panda" else None
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        robot = load_model(name, lock_joints=locks)
    lo, hi = robot.model.lowerPositionLimit, robot.model.upperPositionLimit
    start, goal = lo + 0.35 * (hi - lo), lo + 0.65 * (hi - lo)
    return [f"{x:.6f}" for x in start], [f"{x:.6f}" for x in goal]


def _ur5_targets(n: int, seed: int = 2026) -> list[list[str]]:
    """Positions of the tip frame at ``n`` random in-limit configurations."""
    import pinocchio as pin

    from youbot_opt.robot.load import load_model

    robot = load_model("ur5")
    model, data = robot.model, robot.model.createData()
    frame = model.getFrameId(robot.tip_frame)
    rng = np.random.default_rng(seed)
    lo = np.maximum(model.lowerPositionLimit, -np.pi)
    hi = np.minimum(model.upperPositionLimit, np.pi)
    out = []
    for _ in range(n):
        pin.framesForwardKinematics(model, data, rng.uniform(lo, hi))
        out.append([f"{x:.6f}" for x in data.oMf[frame].translation])
    return out


_CPU: list[float] = []  # CPU time [s] (user + system) of each command, in order


#: Environment variables left out of the runs' environment (``--no-bytecode`` keeps them).
_LEFT_OUT: set[str] = {"PYTHONDONTWRITEBYTECODE"}


def _cache_bytecode() -> None:
    """Compile the package's modules to ``__pycache__``, as installing it does."""
    import compileall

    import youbot_opt

    compileall.compile_dir(Path(youbot_opt.__file__).parent, quiet=1)


def _cli(
    args: list[str], cache: Path, env_extra: dict[str, str] | None = None
) -> tuple[float, subprocess.CompletedProcess[str]]:
    kept = {k: v for k, v in os.environ.items() if k not in _LEFT_OUT}
    env = {**kept, "YOUBOT_OPT_CACHE": str(cache), **(env_extra or {})}
    before = resource.getrusage(resource.RUSAGE_CHILDREN)
    tic = time.perf_counter()
    done = subprocess.run(
        [sys.executable, "-m", "youbot_opt", *args],
        env=env,
        capture_output=True,
        text=True,
        check=False,
    )
    wall = time.perf_counter() - tic
    after = resource.getrusage(resource.RUSAGE_CHILDREN)
    _CPU.append(after.ru_utime + after.ru_stime - before.ru_utime - before.ru_stime)
    return wall, done


#: A lock with no compiler's pid in it yet older than this is stale [s]: the background
#: compiler writes its pid into the lock as it starts.
NO_PID_GRACE = 60.0


def lock_is_stale(lock: Path, now: float | None = None) -> str | None:
    """Why ``lock`` is stale (its compiler is dead, or never started, or it is older than any
    compile: ``codegen.STALE_LOCK``), or None while a compile may still hold it."""
    from youbot_opt.nlp.codegen import STALE_LOCK

    try:
        text = (lock.read_text(errors="replace").split() or [""])[0]  # pid, then the estimate
        age = (time.time() if now is None else now) - lock.stat().st_mtime
    except FileNotFoundError:
        return None  # released meanwhile: not stale, simply gone
    if age > STALE_LOCK:
        return f"{age:.0f} s old, longer than any compile ({STALE_LOCK:.0f} s)"
    if not text.isdigit():
        return f"no compiler pid after {age:.0f} s" if age > NO_PID_GRACE else None
    try:
        os.kill(int(text), 0)
    except ProcessLookupError:
        return f"its compiler (pid {text}) is not running"
    except PermissionError:  # locks are per user: that pid is not this user's compiler
        return f"its pid {text} is another user's process"
    except (OSError, OverflowError):
        return None  # unknown: wait for it
    return None


def _wait_for_background(cache: Path, timeout: float = 900.0) -> float:
    """Wait until no background compile holds a lock in ``cache``; return the wait [s].

    A stale lock (see :func:`lock_is_stale`) is reported and not waited for.
    """
    tic = time.perf_counter()
    while time.perf_counter() - tic < timeout:
        locks = list(cache.rglob("*.lock"))
        stale = {lock: lock_is_stale(lock) for lock in locks}
        if all(stale.values()):  # none left, or only stale ones
            for lock, why in stale.items():
                print(f"  stale compile lock {lock} ({why}): not waiting for it")
            break
        time.sleep(0.5)
    else:
        print(f"  background compiles of {cache} still running after {timeout:.0f} s")
    return time.perf_counter() - tic


def solve_case(
    robot: str, args: list[str], repeats: int, work: Path, compare_jobs: bool = False
) -> dict[str, Any]:
    """Cold then warm runs of one ``solve`` command; medians of ``repeats``."""
    cold, warm, waits, warm_cpu = [], [], [], []
    folder = ""
    summary: dict[str, Any] = {}
    for rep in range(repeats):
        cache = work / f"cache-{robot}-{rep}"
        cache.mkdir()
        for kind, times in (("cold", cold), ("warm", warm)):
            out = work / f"{robot}-{kind}-{rep}"
            wall, done = _cli([*args, "--out", str(out)], cache)
            summary_file = out / "summary.json"
            summary = json.loads(summary_file.read_text()) if summary_file.exists() else {}
            ok = done.returncode == 0 and bool(summary.get("certified"))
            times.append(wall if ok else float("nan"))
            if kind == "warm":
                warm_cpu.append(_CPU[-1])
                folder = str(out)
            if not ok:
                print(f"  {robot} {kind}: exit {done.returncode}\n{done.stderr[-2000:]}")
            if kind == "cold":
                waits.append(_wait_for_background(cache))
    rounds = summary.get("refinement") or {}
    before: dict[str, float] = {}
    if compare_jobs:  # the time to compiled code with one compiler at a time
        cache = work / f"cache-{robot}-one-job"
        cache.mkdir()
        wall, done = _cli(
            [*args, "--out", str(work / f"{robot}-cold-one-job")],
            cache,
            {"YOUBOT_OPT_COMPILE_JOBS": "1"},
        )
        before = {"cold_one_job_s": wall, "background_one_job_s": _wait_for_background(cache)}
    return {
        **before,
        "case": f"solve {robot}",
        "robot": robot,
        "folder": folder,
        "cold_s": statistics.median(cold),
        "warm_s": statistics.median(warm),
        "warm_cpu_s": statistics.median(warm_cpu),
        "background_compile_s": statistics.median(waits),
        "objective": summary.get("objective"),
        "n_knots": summary.get("n_knots"),
        "rounds": len(rounds.get("rounds", [])) if isinstance(rounds, dict) else None,
        "ipopt_s": summary.get("solve_time_s"),
        "files": len(summary.get("files", [])),
    }


def ikpath_case(n: int, repeats: int, reference: int, work: Path) -> dict[str, Any]:
    """The IK path on ur5 through ``n`` position targets, default settings (warm)."""
    cache = work / "cache-ikpath"
    cache.mkdir(exist_ok=True)
    args = ["ikpath", "--robot", "ur5", "--json", "--no-progress"]
    for t in _ur5_targets(n):
        args += ["--target", *t]
    walls, cpus, energy = [], [], float("nan")
    for rep in range(repeats + 1):  # the first run warms the cache
        wall, done = _cli([*args, "--out", str(work / f"ik{n}-{rep}")], cache)
        energy = _energy(done)
        if rep:
            walls.append(wall)
            cpus.append(_CPU[-1])
    row = {
        "case": f"ikpath ur5 {n} targets",
        "wall_s": statistics.median(walls),
        "cpu_s": statistics.median(cpus),
        "E": energy,
    }
    if reference:
        wall, done = _cli(
            [*args, "--starts", str(reference), "--out", str(work / f"ref{n}")], cache
        )
        row.update(reference_starts=reference, reference_wall_s=wall, reference_E=_energy(done))
    return row


def _energy(done: subprocess.CompletedProcess[str]) -> float:
    try:
        payload = json.loads(done.stdout)
    except json.JSONDecodeError:
        print(f"  ikpath: exit {done.returncode}\n{done.stderr[-2000:]}")
        return float("nan")
    return float(payload.get("E", float("nan")))


def main(argv: list[str] | None = None) -> int:
    """Run the cases and print the table (or JSON)."""
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--quick", action="store_true", help="one repeat, no reference starts")
    parser.add_argument("--repeats", type=int, default=3)
    parser.add_argument("--reference-starts", type=int, default=200)
    parser.add_argument("--targets", type=int, nargs="+", default=[4, 6])
    parser.add_argument("--robots", nargs="+", default=list(ROBOTS), choices=ROBOTS)
    parser.add_argument(
        "--compare-jobs", action="store_true", help="also a cold run compiling 1 kernel at a time"
    )
    parser.add_argument("--keep", type=Path, default=None, help="keep the run folders here")
    parser.add_argument("--no-solve", action="store_true")
    parser.add_argument("--no-ikpath", action="store_true")
    parser.add_argument("--json", action="store_true")
    parser.add_argument(
        "--no-bytecode",
        action="store_true",
        help="keep PYTHONDONTWRITEBYTECODE if set (each run then compiles the package)",
    )
    opts = parser.parse_args(argv)
    if opts.no_bytecode:
        _LEFT_OUT.clear()
    else:
        _cache_bytecode()
    repeats = 1 if opts.quick else opts.repeats
    reference = 0 if opts.quick else opts.reference_starts
    load = os.getloadavg()
    rows: list[dict[str, Any]] = []
    with tempfile.TemporaryDirectory(prefix="bench_wait-") as tmp:
        work = Path(tmp) if opts.keep is None else opts.keep
        work.mkdir(parents=True, exist_ok=True)
        if not opts.no_solve:
            cases = {"ur5": ["solve", "--robot", "ur5", "--start", *UR5[0], "--goal", *UR5[1]]}
            for name in ("panda", "xarm7"):
                start, goal = start_goal(name)
                lock = PANDA_LOCK if name == "panda" else []
                cases[name] = ["solve", "--robot", name, *lock, "--start", *start]
                cases[name] += ["--goal", *goal]
            rows += [
                solve_case(name, cases[name], repeats, work, opts.compare_jobs)
                for name in opts.robots
            ]
        if not opts.no_ikpath:
            rows += [ikpath_case(n, repeats, reference, work) for n in opts.targets]
    if opts.json:
        print(
            json.dumps(
                {"load_average": load, "bytecode_cached": not opts.no_bytecode, "rows": rows},
                indent=1,
            )
        )
        return 0
    bytecode = "as the environment has it" if opts.no_bytecode else "cached, as an install"
    print(f"load average {load[0]:.2f} {load[1]:.2f} {load[2]:.2f}; {repeats} repeat(s), medians; "
          f"bytecode {bytecode}")  # fmt: skip
    print(f"{'case':<24}{'cold [s]':>9}{'warm [s]':>9}{'cpu [s]':>8}{'bg [s]':>8}{'IPOPT [s]':>10}"
          f"{'knots':>6}{'rounds':>7}{'f':>12}{'files':>6}")  # fmt: skip
    for r in rows:
        if r["case"].startswith("solve"):
            print(f"{r['case']:<24}{r['cold_s']:>9.2f}{r['warm_s']:>9.2f}{r['warm_cpu_s']:>8.2f}"
                  f"{r['background_compile_s']:>8.1f}{r['ipopt_s'] or float('nan'):>10.3f}"
                  f"{r['n_knots'] or 0:>6}{r['rounds'] or 0:>7}"
                  f"{r['objective'] or float('nan'):>12.4f}"
                  f"{r['files']:>6}")  # fmt: skip
    print(f"targets: warm <= {TARGETS['warm']} s, cold <= {TARGETS['cold']} s, vendor arms "
          f"({', '.join(sorted(VENDOR))}) 2x "
          "(cpu: the warm command's user + system CPU time; bg: wait for the cold run's "
          "background compile after it returned)")  # fmt: skip
    print(f"\n{'case':<24}{'cold/target':>12}{'warm/target':>12}  warm run folder")
    for r in rows:
        if r["case"].startswith("solve"):
            print(f"{r['case']:<24}{r['cold_s'] / _target(r['robot'], 'cold'):>12.2f}"
                  f"{r['warm_s'] / _target(r['robot'], 'warm'):>12.2f}  {r['folder']}")  # fmt: skip
    jobs = [r for r in rows if "background_one_job_s" in r]
    if jobs:
        print(f"\n{'time to compiled code':<24}{'1 at a time':>12}{'default':>10}"
              f"{'cold, 1':>9}{'cold':>7}")  # fmt: skip
        for r in jobs:
            print(f"{r['case']:<24}{r['background_one_job_s']:>12.1f}"
                  f"{r['background_compile_s']:>10.1f}{r['cold_one_job_s']:>9.2f}"
                  f"{r['cold_s']:>7.2f}")  # fmt: skip
    ik = [r for r in rows if r["case"].startswith("ikpath")]
    if ik:
        print(f"\n{'case':<24}{'wall [s]':>9}{'cpu [s]':>8}{'E default':>11}{'ref starts':>11}"
              f"{'ref E':>10}{'ref wall':>9}{'E / ref':>8}")  # fmt: skip
        for r in ik:
            ref = r.get("reference_E", float("nan"))
            print(f"{r['case']:<24}{r['wall_s']:>9.2f}{r['cpu_s']:>8.2f}{r['E']:>11.4f}"
                  f"{r.get('reference_starts', 0):>11}{ref:>10.4f}"
                  f"{r.get('reference_wall_s', float('nan')):>9.1f}"
                  f"{r['E'] / ref:>8.3f}")  # fmt: skip
        print(f"target: the best known E by default in <= {TARGETS['ikpath']} s")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())

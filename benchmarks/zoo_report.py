"""Zoo report: every fixed-base arm and manipulator of example-robot-data, end to end.

Run ``python benchmarks/zoo_report.py [--quick] [--only NAME ...] [--out docs/robots.md]``.

For each robot of the installed example-robot-data whose package is an arm or
a manipulator (:data:`ARM_PACKAGES`, plus talos' single arm), found from the
installed files: load it (default, then ``strict=False`` if the default
refuses it), plan a rest-to-rest motion between two in-limit configurations
(35 % and 65 % of each joint's range; ±1 rad for a continuous joint) with
Hermite-Simpson collocation (40 knots, 20 with ``--quick``, beta = 0.5, the
dynamics in CasADi's virtual machine so the report never waits for a C
compiler), certify it by forward simulation with ``pin.aba``, and write the
meshcat replay as a standalone HTML file to measure its size. The table goes to
``docs/robots.md`` with what loads, solves, certifies and why not.
"""

from __future__ import annotations

import argparse
import dataclasses
import inspect
import json
import logging
import math
import os
import subprocess
import sys
import tempfile
import time
import warnings
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from youbot_opt.dynamics.coordinates import angle_robot, continuous_joints
from youbot_opt.exceptions import YoubotOptError
from youbot_opt.robot.model import (
    RobotModel,
    example_robot_data_dir,
    example_robots,
    load_model,
)
from youbot_opt.trajopt.certify import certify
from youbot_opt.trajopt.problem import BoundaryState, TrajOptProblem
from youbot_opt.trajopt.solver import TrajOptSolver

ARM_PACKAGES: tuple[str, ...] = (
    "ur_description",
    "panda_description",
    "so_arm_description",
    "z1_description",
    "xarm_description",
    "kinova_description",
    "finger_edu_description",
    "baxter_description",
    "double_pendulum_description",
    "asr_twodof_description",
    "allegro_hand_description",
)
"""example-robot-data packages whose robots are fixed-base arms or manipulators."""
EXTRA_ARMS: tuple[str, ...] = ("talos_left_arm",)
"""Single arms shipped inside a humanoid's package."""
ROOT = Path(__file__).resolve().parent.parent
TIMEOUT = 240.0  # [s] per robot (load + solve + certify + replay), in its own process
_CHILD = "--child"


@dataclass
class Row:
    """One robot's outcome; an empty ``why`` means it went all the way."""

    name: str
    dof: str = ""
    joints: str = ""
    loads: str = "no"
    solves: str = "-"
    certified: str = "-"
    html_kb: str = "-"
    seconds: float = 0.0
    notes: list[str] = field(default_factory=list)


def arm_robots() -> dict[str, Path]:
    """Return the arms and manipulators of the installed example-robot-data: name -> URDF."""
    robots = example_robots()
    return {
        name: path
        for name, path in robots.items()
        if any(part in ARM_PACKAGES for part in path.parts) or name in EXTRA_ARMS
    }


def _load(name: str, row: Row) -> RobotModel | None:
    lenient = "strict" in inspect.signature(load_model).parameters
    for strict in (True, False) if lenient else (True,):
        with warnings.catch_warnings(record=True) as caught:
            warnings.simplefilter("always")
            try:
                robot = load_model(name, strict=strict) if not strict else load_model(name)
            except YoubotOptError as exc:
                row.notes.append(f"{'refused' if strict else 'lenient refused'}: {_short(exc)}")
                continue
        row.loads = "yes" if strict else "lenient"
        row.notes += [_short(w.message) for w in caught if "mimic" in str(w.message)]
        return robot
    return None


def _short(message: object, limit: int = 160) -> str:
    text = " ".join(str(message).split()).replace("|", "/")
    text = text.replace(f"{example_robot_data_dir()}/example-robot-data/robots/", "")
    return text if len(text) <= limit else text[: limit - 3] + "..."


def _joint_summary(robot: RobotModel) -> str:
    model = robot.model
    continuous = len(continuous_joints(model))
    kinds = []
    if continuous:
        kinds.append(f"{continuous} continuous")
    if robot_locked := getattr(robot, "locked_joints", ()):
        kinds.append(f"{len(robot_locked)} locked")
    return ", ".join(kinds) or "revolute/prismatic"


def _boundary(robot: RobotModel) -> tuple[np.ndarray, np.ndarray]:
    bounds = robot.bounds()
    lo = np.where(np.isfinite(bounds.q_lower), bounds.q_lower, -1.0)
    hi = np.where(np.isfinite(bounds.q_upper), bounds.q_upper, 1.0)
    return lo + 0.35 * (hi - lo), lo + 0.65 * (hi - lo)


def run_robot(name: str, n_knots: int, out_dir: Path) -> Row:
    """Load, solve, certify and replay one robot; never raises."""
    row = Row(name=name)
    tic = time.perf_counter()
    robot = _load(name, row)
    if robot is None:
        row.seconds = time.perf_counter() - tic
        return row
    twin = angle_robot(robot)
    row.dof = f"{robot.nq}/{robot.nv}"
    row.joints = _joint_summary(robot)
    print("row " + json.dumps(dataclasses.asdict(row)), flush=True)
    missing = [
        twin.joint_names[i]
        for i in range(twin.nv)
        if not (twin.velocity_limit[i] > 0 and twin.effort_limit[i] > 0)
    ]
    if missing:
        row.solves = "no"
        row.notes.append(
            f"the file gives no velocity or effort limit (0) for {', '.join(missing[:4])}"
            + (" ..." if len(missing) > 4 else "")
        )
        row.seconds = time.perf_counter() - tic
        return row
    q0, q1 = _boundary(twin)
    _stage("solve")
    try:
        problem = TrajOptProblem(
            robot=twin, start=BoundaryState(q=q0), goal=BoundaryState(q=q1), n_knots=n_knots
        )
        result = TrajOptSolver(problem, "hermite_simpson", compile=False).solve(beta=0.5)
    except YoubotOptError as exc:
        row.solves = "no"
        row.notes.append(f"build/solve error: {_short(exc)}")
        row.seconds = time.perf_counter() - tic
        return row
    row.solves = "yes" if result.success else f"no ({result.status.value})"
    print("row " + json.dumps(dataclasses.asdict(row)), flush=True)
    if result.trajectory is not None:
        _stage("certify")
        try:
            certificate = certify(result)
            row.certified = "yes" if certificate.ok else "no"
            if not certificate.ok:
                row.notes.append("certificate: " + "; ".join(certificate.failures())[:200])
        except YoubotOptError as exc:
            row.certified = "error"
            row.notes.append(f"certify error: {_short(exc)}")
        _stage("replay")
        try:
            from youbot_opt.viz.meshcat.replay import export_html

            page = export_html(
                twin,
                result.trajectory.t,
                result.trajectory.q,
                out_dir / f"{name.replace('/', '_')}.html",
            )
            row.html_kb = f"{page.stat().st_size / 1e3:.0f}"
        except Exception as exc:  # noqa: BLE001 - a report records every failure and goes on
            row.notes.append(f"replay failed: {type(exc).__name__}: {_short(exc)}")
    row.seconds = time.perf_counter() - tic
    return row


def _stage(name: str) -> None:
    print(f"stage {name}", flush=True)


def _run_isolated(name: str, n_knots: int, out_dir: Path, timeout: float) -> Row:
    """run_robot in a child process, so that a hanging integration costs ``timeout`` only."""
    cmd = [sys.executable, __file__, _CHILD, name, str(n_knots), str(out_dir)]
    tic = time.perf_counter()
    try:
        done = subprocess.run(cmd, capture_output=True, text=True, timeout=timeout)
    except subprocess.TimeoutExpired as exc:
        out = exc.stdout.decode() if isinstance(exc.stdout, bytes) else (exc.stdout or "")
        stages = [line.split()[1] for line in out.splitlines() if line.startswith("stage ")]
        row = Row(name=name, seconds=time.perf_counter() - tic)
        for line in out.splitlines():
            if line.startswith("row "):
                row = Row(**json.loads(line[4:]))
        stage = stages[-1] if stages else "load"
        row.notes.append(f"timed out after {timeout:.0f} s in {stage}")
        if stage == "certify":
            row.certified = "timeout"
        elif stage == "solve":
            row.solves = "timeout"
        row.seconds = time.perf_counter() - tic
        return row
    row = Row(name=name)
    for line in done.stdout.splitlines():
        if line.startswith("result "):
            return Row(**json.loads(line[7:]))
        if line.startswith("row "):
            row = Row(**json.loads(line[4:]))
    row.notes.append(f"crashed: {_short(done.stderr.strip().splitlines()[-1:])}")
    return row


def _table(rows: list[Row], n_knots: int) -> str:
    loaded = sum(r.loads != "no" for r in rows)
    solved = sum(r.solves == "yes" for r in rows)
    certified = sum(r.certified == "yes" for r in rows)
    lines = [
        "# The robot zoo: what loads, solves and is certified",
        "",
        "Generated by `python benchmarks/zoo_report.py` (do not edit by hand): every",
        "fixed-base arm and manipulator of the installed example-robot-data, a",
        "rest-to-rest motion between 35 % and 65 % of each joint's range (±1 rad for a",
        f"continuous joint), Hermite-Simpson, {n_knots} knots, beta = 0.5, certified by",
        "forward simulation with `pin.aba` (`youbot_opt.trajopt.certify`), replayed as a",
        "standalone meshcat page. `dof` is Pinocchio's nq/nv after locking; continuous",
        "joints are planned in angle coordinates (docs/design.md).",
        "",
        f"**{len(rows)} robots: {loaded} load, {solved} solve, {certified} certified.**",
        "",
        "| robot | nq/nv | joints | loads | solves | certified | replay [kB] | time [s] | notes |",
        "|---|---|---|---|---|---|---|---|---|",
    ]
    for r in rows:
        notes = "; ".join(r.notes) or ""
        lines.append(
            f"| {r.name} | {r.dof} | {r.joints} | {r.loads} | {r.solves} | {r.certified} "
            f"| {r.html_kb} | {r.seconds:.1f} | {notes} |"
        )
    return "\n".join(lines) + "\n"


def main(argv: list[str] | None = None) -> int:
    """Run the report and write the table."""
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--quick", action="store_true", help="20 knots instead of 40")
    parser.add_argument("--only", nargs="+", help="robot names (default: all arms)")
    parser.add_argument("--out", type=Path, default=ROOT / "docs" / "robots.md")
    parser.add_argument("--timeout", type=float, default=TIMEOUT, help="[s] per robot")
    args = parser.parse_args(argv)
    logging.basicConfig(level=logging.WARNING)
    n_knots = 20 if args.quick else 40
    names = args.only or sorted(arm_robots())
    rows = []
    with tempfile.TemporaryDirectory(prefix="youbot_zoo_") as tmp:
        for name in names:
            row = _run_isolated(name, n_knots, Path(tmp), args.timeout)
            print(
                f"{name:>28}: loads {row.loads}, solves {row.solves}, certified {row.certified}, "
                f"{row.seconds:.1f} s {'; '.join(row.notes)[:150]}",
                flush=True,
            )
            rows.append(row)
    text = _table(rows, n_knots)
    tmp_out = args.out.with_suffix(".tmp")
    tmp_out.write_text(text)
    os.replace(tmp_out, args.out)
    print(f"wrote {args.out} ({math.fsum(r.seconds for r in rows):.0f} s of robots)")
    return 0


if __name__ == "__main__":
    if len(sys.argv) == 5 and sys.argv[1] == _CHILD:
        warnings.simplefilter("ignore", RuntimeWarning)  # NaN steps of a failing integration
        result = run_robot(sys.argv[2], int(sys.argv[3]), Path(sys.argv[4]))
        print("result " + json.dumps(dataclasses.asdict(result)), flush=True)
        raise SystemExit(0)
    raise SystemExit(main())

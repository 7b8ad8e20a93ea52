"""Zoo report: every fixed-base arm and manipulator of example-robot-data, end to end.

Run ``python benchmarks/zoo_report.py [--quick] [--only NAME ...] [--out docs/robots.md]``.

For each robot of the installed example-robot-data whose package is an arm or
a manipulator (:data:`ARM_PACKAGES`, plus talos' single arm): load it (default,
then ``strict=False``), plan a rest-to-rest motion between 35 % and 65 % of each
joint's range (±1 rad for a continuous joint) as a user gets it: the transcription
``method="auto"`` picks (Radau IIA where the joint damping is stiff on the grid,
else Hermite-Simpson; ``--transcription`` to force one) on 40 knots (20 with
``--quick``), beta = 0.5, then adaptive refinement
(:func:`~youbot_opt.trajopt.refine.refine`, budget :func:`budget`) until the
plan is certified by forward simulation or the budget runs out; the dynamics
run in CasADi's virtual machine. The table (``docs/robots.md``) shows the fixed
grid's certificate next to the refined outcome, and the meshcat replay's size.
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
from collections.abc import Callable
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from youbot_opt.dynamics.coordinates import angle_robot, continuous_joints
from youbot_opt.exceptions import YoubotOptError
from youbot_opt.nlp.status import SolveStatus
from youbot_opt.robot.catalogue import example_robot_data_dir, example_robots
from youbot_opt.robot.load import load_model
from youbot_opt.robot.model import RobotModel
from youbot_opt.trajopt.problem import BoundaryState, TrajOptProblem
from youbot_opt.trajopt.refine import RefinementBudget, RefinementRound, refine
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
TIMEOUT = 240.0  # [s] per robot (load + solve + refine + replay), in its own process
TIME_LIMIT = 60.0  # [s] refinement budget per robot (no new round, certificate cut short)
MAX_KNOTS = 1000
MAX_ROUNDS = 8
ERROR_TOL = 1e-3
_CHILD = "--child"


@dataclass
class Row:
    """One robot's outcome; an empty ``why`` means it went all the way."""

    name: str
    dof: str = ""
    joints: str = ""
    loads: str = "no"
    solves: str = "-"
    fixed_certified: str = "-"
    fixed_plan: str = "-"
    certified: str = "-"
    knots: str = "-"
    rounds: str = "-"
    objective: str = "-"
    duration: str = "-"
    html_kb: str = "-"
    scheme: str = "-"
    why: str = ""
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


METHOD_NAMES: dict[str, str] = {
    "hermite_simpson": "Hermite-Simpson",
    "trapezoidal": "trapezoidal collocation",
    "radau": "Radau IIA collocation",
    "auto": (
        'the transcription `method="auto"` picks (Radau IIA where the joint damping '
        "is stiff on the grid, else Hermite-Simpson; column `scheme`)"
    ),
}
"""Transcriptions the report can use (``--transcription``) and their names in the table."""


def budget(time_limit: float = TIME_LIMIT) -> RefinementBudget:
    """The refinement budget of every robot: the command line's defaults and a time limit."""
    return RefinementBudget(
        tolerance=ERROR_TOL, max_rounds=MAX_ROUNDS, max_knots=MAX_KNOTS, time_limit=time_limit
    )


def _certificate_word(passed: bool | None, failures: tuple[str, ...]) -> str:
    if passed is None:
        return "-"
    if passed:
        return "yes"
    return "no (cut short)" if any(f.startswith("incomplete") for f in failures) else "no"


def _progress(row: Row) -> Callable[[RefinementRound], None]:
    def report(record: RefinementRound) -> None:
        if record.index == 0:
            row.solves = "yes" if SolveStatus(record.status).success else f"no ({record.status})"
            row.fixed_certified = _certificate_word(record.certificate_passed, record.failures)
            row.fixed_plan = f"{record.objective:.6g} / {record.duration:.4g}"
            if record.certificate_passed is False:
                row.notes.append(f"{row.knots} knots: " + "; ".join(record.failures)[:160])
        row.rounds = str(record.index)
        row.knots = str(record.n_knots)
        row.objective = f"{record.objective:.6g}"
        row.duration = f"{record.duration:.4g}"
        print("row " + json.dumps(dataclasses.asdict(row)), flush=True)
        _stage("refine")

    return report


def run_robot(
    name: str,
    n_knots: int,
    out_dir: Path,
    time_limit: float = TIME_LIMIT,
    method: str = "auto",
) -> Row:
    """Load, solve (with transcription ``method``), refine and replay one robot; never raises."""
    row = Row(name=name)
    tic = time.perf_counter()
    robot = _load(name, row)
    if robot is None:
        row.seconds = time.perf_counter() - tic
        return row
    twin = angle_robot(robot)
    row.dof = f"{robot.nq}/{robot.nv}"
    row.joints = _joint_summary(robot)
    row.knots = str(n_knots)
    print("row " + json.dumps(dataclasses.asdict(row)), flush=True)
    missing = [
        twin.joint_names[i]
        for i in range(twin.nv)
        if not (twin.velocity_limit[i] > 0 and twin.effort_limit[i] > 0)
    ]
    if missing:
        row.solves = "no"
        row.why = f"the file gives no velocity or effort limit (0) for {', '.join(missing[:4])}" + (
            " ..." if len(missing) > 4 else ""
        )
        row.seconds = time.perf_counter() - tic
        return row
    q0, q1 = _boundary(twin)
    _stage("solve")
    try:
        problem = TrajOptProblem(
            robot=twin, start=BoundaryState(q=q0), goal=BoundaryState(q=q1), n_knots=n_knots
        )
        solver = TrajOptSolver(problem, method, compile=False)
        row.scheme = solver.method.name
        result, refinement = refine(
            solver, beta=0.5, budget=budget(time_limit), progress=_progress(row)
        )
    except YoubotOptError as exc:
        row.solves = "no" if row.solves == "-" else row.solves
        row.why = f"build/solve error: {_short(exc)}"
        row.seconds = time.perf_counter() - tic
        return row
    if refinement is not None:
        row.certified = "yes" if refinement.certified else "no"
        if not refinement.certified:
            row.why = _short(refinement.reason.split(" (budget: ")[0], limit=400)
            last = refinement.rounds[-1] if refinement.rounds else None
            if last is not None and last.certificate_passed is False:
                row.why += f"; last certificate ({last.n_knots} knots): " + _short(
                    "; ".join(last.failures[:2]), limit=200
                )
    print("row " + json.dumps(dataclasses.asdict(row)), flush=True)
    if result.trajectory is not None:
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


def _run_isolated(
    name: str, n_knots: int, out_dir: Path, timeout: float, time_limit: float, method: str
) -> Row:
    """run_robot in a child process, so that a hanging integration costs ``timeout`` only."""
    cmd = [sys.executable, __file__, _CHILD, name, str(n_knots), str(out_dir), str(time_limit)]
    cmd.append(method)
    tic = time.perf_counter()
    try:
        done = subprocess.run(cmd, capture_output=True, text=True, timeout=timeout)
    except subprocess.TimeoutExpired as exc:
        out = exc.stdout.decode() if isinstance(exc.stdout, bytes) else (exc.stdout or "")
        stages = [line.split()[1] for line in out.splitlines() if line.startswith("stage ")]
        row = Row(name=name)
        for line in out.splitlines():
            if line.startswith("row "):
                row = Row(**json.loads(line[4:]))
        stage = stages[-1] if stages else "load"
        if stage == "refine":
            row.certified = "timeout"
        elif stage == "solve":
            row.solves = "timeout"
        row.why = f"the process timed out after {timeout:.0f} s in {stage}"
        row.seconds = time.perf_counter() - tic
        return row
    row = Row(name=name)
    for line in done.stdout.splitlines():
        if line.startswith("result "):
            return Row(**json.loads(line[7:]))
        if line.startswith("row "):
            row = Row(**json.loads(line[4:]))
    row.why = f"crashed: {_short(done.stderr.strip().splitlines()[-1:])}"
    row.seconds = time.perf_counter() - tic
    return row


def _table(rows: list[Row], n_knots: int, time_limit: float, wall: float, method: str) -> str:
    loaded = sum(r.loads != "no" for r in rows)
    solved = sum(r.solves == "yes" for r in rows)
    fixed = sum(r.fixed_certified == "yes" for r in rows)
    certified = sum(r.certified == "yes" for r in rows)
    lines = [
        "# The robot zoo: what loads, solves and is certified",
        "",
        "Generated by `python benchmarks/zoo_report.py` (do not edit by hand): every",
        "fixed-base arm and manipulator of the installed example-robot-data, a",
        "rest-to-rest motion between 35 % and 65 % of each joint's range (±1 rad for a",
        f"continuous joint), {METHOD_NAMES[method]} from {n_knots} uniform knots, beta = 0.5, then",
        "adaptive mesh refinement as `youbot-opt solve` does by default",
        "(`youbot_opt.trajopt.refine.refine`, docs/refinement.md) with the budget",
        f"**{budget(time_limit).describe()} per robot**. Certified means every interval's",
        "collocation error is within the tolerance and the forward simulation with",
        "`pin.aba` passes (`youbot_opt.trajopt.certify`); when the time limit is reached",
        "the certificate is cut short and fails. The final plan is replayed as a",
        "standalone meshcat page. `dof` is Pinocchio's nq/nv after locking; continuous",
        "joints are planned in angle coordinates (docs/design.md).",
        "",
        f"Columns: `solves` is the first, {n_knots}-knot solve; `certified, {n_knots} knots` is",
        "that fixed grid's forward-simulation certificate alone (what this report showed",
        "before refinement); `certified` is the outcome after refinement, which also",
        f"requires the error tolerance; `f / T, {n_knots} knots` is that solve's objective and",
        "duration [s]; `scheme` is the transcription; `knots`, `rounds` (refinement",
        "rounds after the first solve), `f`",
        "and `T [s]` are the final grid's; `time [s]` is the robot's wall time (load,",
        "solves, certificates, replay); `why not` is the refinement's reason and its last",
        "certificate's failures.",
        "",
        f"**{len(rows)} robots: {loaded} load, {solved} solve, {fixed} certified on the fixed "
        f"{n_knots}-knot grid, {certified} certified after refinement.** "
        f"Total run time {wall:.0f} s.",
        "",
        f"| robot | nq/nv | joints | loads | solves | f / T, {n_knots} knots "
        f"| certified, {n_knots} knots | certified | scheme "
        "| knots | rounds | f | T [s] | time [s] | replay [kB] | why not | notes |",
        "|---|---|---|---|---|---|---|---|---|---|---|---|---|---|---|---|---|",
    ]
    for r in rows:
        notes = "; ".join(r.notes) or ""
        lines.append(
            f"| {r.name} | {r.dof} | {r.joints} | {r.loads} | {r.solves} | {r.fixed_plan} "
            f"| {r.fixed_certified} "
            f"| {r.certified} | {r.scheme} | {r.knots} | {r.rounds} | {r.objective} | {r.duration} "
            f"| {r.seconds:.1f} | {r.html_kb} | {r.why} | {notes} |"
        )
    return "\n".join(lines) + "\n"


def main(argv: list[str] | None = None) -> int:
    """Run the report and write the table."""
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--quick", action="store_true", help="start from 20 knots instead of 40")
    parser.add_argument("--only", nargs="+", help="robot names (default: all arms)")
    parser.add_argument("--out", type=Path, default=ROOT / "docs" / "robots.md")
    parser.add_argument("--timeout", type=float, default=TIMEOUT, help="[s] per robot process")
    parser.add_argument(
        "--time-limit", type=float, default=TIME_LIMIT, help="[s] refinement budget per robot"
    )
    parser.add_argument(
        "--transcription",
        choices=sorted(METHOD_NAMES),
        default="auto",
        help="collocation scheme (default auto: radau where the damping is stiff, else "
        "hermite_simpson)",
    )
    args = parser.parse_args(argv)
    logging.basicConfig(level=logging.WARNING)
    n_knots = 20 if args.quick else 40
    names = args.only or sorted(arm_robots())
    rows = []
    tic = time.perf_counter()
    with tempfile.TemporaryDirectory(prefix="youbot_zoo_") as tmp:
        for name in names:
            row = _run_isolated(
                name, n_knots, Path(tmp), args.timeout, args.time_limit, args.transcription
            )
            print(
                f"{name:>28}: loads {row.loads}, solves {row.solves}, certified "
                f"{row.fixed_certified} -> {row.certified} ({row.knots} knots, {row.rounds} "
                f"rounds), {row.seconds:.1f} s {row.why[:150]}",
                flush=True,
            )
            rows.append(row)
    wall = time.perf_counter() - tic
    text = _table(rows, n_knots, args.time_limit, wall, args.transcription)
    tmp_out = args.out.with_suffix(".tmp")
    tmp_out.write_text(text)
    os.replace(tmp_out, args.out)
    print(f"wrote {args.out} ({math.fsum(r.seconds for r in rows):.0f} s of robots, {wall:.0f} s)")
    return 0


if __name__ == "__main__":
    if len(sys.argv) == 7 and sys.argv[1] == _CHILD:
        warnings.simplefilter("ignore", RuntimeWarning)  # NaN steps of a failing integration
        result = run_robot(
            sys.argv[2], int(sys.argv[3]), Path(sys.argv[4]), float(sys.argv[5]), sys.argv[6]
        )
        print("result " + json.dumps(dataclasses.asdict(result)), flush=True)
        raise SystemExit(0)
    raise SystemExit(main())

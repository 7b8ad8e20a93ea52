"""Every command's arguments: the argument parser of ``youbot-opt``, apart from the commands.

:func:`build_parser` adds each command of :data:`COMMANDS` with its flags and
its help; the parser imports only the standard library, so ``--help`` and an
argument error stay fast (no NumPy, CasADi, Pinocchio or matplotlib). The
commands' modules are imported by :func:`youbot_opt.cli.main` once a command
is chosen. Choices the library owns are spelled out here; a test checks them
against the library.

>>> args = build_parser().parse_args(["solve", "--knots", "20"])
>>> COMMANDS[args.command]
('solve', 'run')
"""

from __future__ import annotations

import argparse
import math
import re
import sys
from collections.abc import Callable, Sequence
from pathlib import Path
from typing import NoReturn

from youbot_opt._version import __version__

__all__ = [
    "COMMANDS",
    "DEFAULT_COMMAND",
    "DEFAULT_TRANSCRIPTION",
    "EXAMPLE_NAMES",
    "HESSIAN_NAMES",
    "LINEAR_SOLVER_NAMES",
    "MAX_ITER_LIMIT",
    "METHOD_NAMES",
    "SEED_LIMIT",
    "START_KIND_NAMES",
    "build_parser",
    "cut_long_values",
    "MAX_SEGMENT_TIME",
    "float_in_range",
    "int_in_range",
    "out_arg",
    "parse_lock",
    "shard_arg",
]

#: Each command, in ``--help`` order: the module of :mod:`youbot_opt.cli` that runs it and
#: the function of that module called with the parsed arguments.
COMMANDS: dict[str, tuple[str, str]] = {
    "main": ("main_command", "run"),
    "solve": ("solve", "run"),
    "report": ("report", "run"),
    "robots": ("robots", "run"),
    "multistart": ("studies", "multistart"),
    "pareto": ("studies", "pareto"),
    "bounds": ("studies", "bounds"),
    "reproduce-study1": ("reproduce", "run"),
    "ikpath": ("ikpath", "run"),
    "export": ("export", "run_export"),
}

DEFAULT_COMMAND = "main"
"""The command of a bare ``youbot-opt`` (or one that starts with an option)."""

DEFAULT_TRANSCRIPTION = "radau"
"""``solve``'s transcription on any robot but the study's youBot (docs/refinement.md)."""

#: Largest ``--max-iter``: IPOPT stores its iteration cap in a 32-bit int.
MAX_ITER_LIMIT = 2**31 - 1
#: Longest ``ikpath --segment-time`` [s]: a minute per move already replays slower than any arm.
MAX_SEGMENT_TIME = 60.0
#: Largest ``--seed``: NumPy's legacy seeds (the spline guesses) are 32-bit.
SEED_LIMIT = 2**32 - 1

# The library's choices, spelled out so that building the parser imports no solver;
# tests/cli/test_cli_help.py checks them against nlp.ipopt.LINEAR_SOLVERS and HessianMode,
# and ikpath's EXAMPLES, METHODS and START_KINDS.
HESSIAN_NAMES: tuple[str, ...] = ("auto", "exact", "limited-memory")
LINEAR_SOLVER_NAMES: tuple[str, ...] = (
    "mumps",
    "spral",
    "ma27",
    "ma57",
    "ma77",
    "ma86",
    "ma97",
    "pardiso",
)
EXAMPLE_NAMES: tuple[str, ...] = ("A", "B")
METHOD_NAMES: tuple[str, ...] = ("al", "ipopt")
START_KIND_NAMES: tuple[str, ...] = ("feasible", "uniform")
SPATIAL_START_KIND_NAMES: tuple[str, ...] = ("mixed", "coherent", "random")
PLANAR_REACH_EVALUATIONS = 20_000
SPATIAL_REACH_BOXES = 200_000  # ikpath.reachability.interval's default boxes per target
SPATIAL_REACH_SECONDS = 1.0  # and its default time per target [s]

_ARGV: list[str] = []  # the command line being parsed, for the parser's error messages


# ------------------------------------------------------------------ error messages
def cut_long_values(message: str, argv: Sequence[str] = ()) -> str:
    """Cut, in an error message, every echoed value longer than ``MAX_SHOWN_CHARS``.

    The values of ``argv`` (also the ``VALUE`` of ``--flag=VALUE``) are cut
    where they appear, spaces and all; any other run of more than
    ``MAX_SHOWN_CHARS`` non-space characters is cut too. Each cut ends in
    ``… (N characters)``.
    """
    # Only an error needs the limit: _checks imports NumPy, which --help must not.
    from youbot_opt._checks import MAX_SHOWN_CHARS

    def cut(text: str) -> str:
        return f"{text[:MAX_SHOWN_CHARS]}… ({len(text)} characters)"

    values = {a.split("=", 1)[1] if a.startswith("--") and "=" in a else a for a in argv}
    for value in sorted((v for v in values if len(v) > MAX_SHOWN_CHARS), key=len, reverse=True):
        message = message.replace(value, cut(value))
    return re.sub(rf"\S{{{MAX_SHOWN_CHARS + 1},}}", lambda m: cut(m.group()), message)


class _Parser(argparse.ArgumentParser):
    """An argument parser whose error messages cut long values (sub-parsers are one too)."""

    def error(self, message: str) -> NoReturn:
        super().error(cut_long_values(message, _ARGV or sys.argv[1:]))


class _Renamed(argparse.Action):
    """A flag that is not one: refused with a message naming the flag to use."""

    def __init__(self, option_strings: list[str], dest: str, *, use: str, **kwargs: object) -> None:
        super().__init__(option_strings, dest, nargs="?", help=argparse.SUPPRESS)
        self.use = use

    def __call__(
        self,
        parser: argparse.ArgumentParser,
        namespace: argparse.Namespace,
        values: object,
        option_string: str | None = None,
    ) -> None:
        parser.error(f"{option_string} is not an option: use {self.use}")


# ------------------------------------------------------------------ argument types
def shard_arg(text: str) -> tuple[int, int]:
    """Parse ``--shard I/K`` (``1 <= I <= K``) into ``(I, K)``.

    Raises
    ------
    argparse.ArgumentTypeError
        If ``text`` is not two integers ``I/K`` with ``1 <= I <= K``.
    """
    try:
        i, k = (int(x) for x in text.split("/"))
    except ValueError:
        i = k = 0
    if not 1 <= i <= k:
        raise argparse.ArgumentTypeError(f"expected I/K with 1 <= I <= K, e.g. 2/8; got {text!r}")
    return i, k


def int_in_range(flag: str, lo: int, hi: int) -> Callable[[str], int]:
    """Return an argparse ``type`` for an int in ``lo..hi`` (errors name flag, value, range)."""

    def parse(text: str) -> int:
        try:
            value = int(text)
        except ValueError:
            raise argparse.ArgumentTypeError(
                f"{flag} must be an integer in {lo}..{hi}, got {text!r}"
            ) from None
        if not lo <= value <= hi:
            raise argparse.ArgumentTypeError(f"{flag} must be in {lo}..{hi}, got {value}")
        return value

    return parse


def float_in_range(flag: str, lo: float, hi: float) -> Callable[[str], float]:
    """Return an argparse ``type``: a number in ``(lo, hi]``, else an error naming the range."""

    def parse(text: str) -> float:
        try:
            value = float(text)
        except ValueError:
            raise argparse.ArgumentTypeError(
                f"{flag} must be a number in ({lo:g}, {hi:g}], got {text!r}"
            ) from None
        if not lo < value <= hi:
            raise argparse.ArgumentTypeError(f"{flag} must be in ({lo:g}, {hi:g}], got {text}")
        return value

    return parse


def out_arg(text: str) -> str:
    """Parse ``--out DIR``: any path but the empty one (which would mean the current folder).

    Raises
    ------
    argparse.ArgumentTypeError
        If ``text`` is empty or only spaces.
    """
    if not text.strip():
        raise argparse.ArgumentTypeError(
            "must name a folder, got an empty path (use --out . for the current folder)"
        )
    return text


def parse_lock(text: str) -> tuple[str, float]:
    """Parse one ``--lock NAME=VALUE`` (VALUE in [rad] or [m]).

    Parameters
    ----------
    text : str
        ``"joint_name=0.5"``.

    Returns
    -------
    tuple of (str, float)
        The joint name and its position.

    Raises
    ------
    argparse.ArgumentTypeError
        If ``text`` is not ``NAME=VALUE`` with a finite number.
    """
    name, sep, value = text.rpartition("=")
    try:
        number = float(value)
    except ValueError:
        number = math.nan
    if not sep or not name.strip() or not math.isfinite(number):
        raise argparse.ArgumentTypeError(
            f"expected NAME=VALUE with a finite VALUE in rad (or m), got {text!r}"
        )
    return name.strip(), number


# ------------------------------------------------------------------ shared flags
def _scheduler_args(p: argparse._ActionsContainer, *, shard: bool = True) -> None:
    """Add ``--scheduler`` / ``--scheduler-file`` (mutually exclusive) and ``--shard`` to ``p``.

    ``shard=False`` leaves ``--shard`` out (a command whose sweep keeps no store).
    """
    g = p.add_mutually_exclusive_group()
    g.add_argument(
        "--scheduler",
        default=None,
        metavar="ADDRESS",
        help="run the items on this Dask scheduler, e.g. tcp://10.0.0.5:8786 "
        "(needs youbot_opt[dask]; see docs/scaling.md)",
    )
    g.add_argument(
        "--scheduler-file",
        default=None,
        metavar="FILE",
        help="run the items on the Dask scheduler described by FILE "
        "(written by 'dask scheduler --scheduler-file FILE' or dask-jobqueue)",
    )
    if not shard:
        return
    p.add_argument(
        "--shard",
        type=shard_arg,
        default=None,
        metavar="I/K",
        help="solve only share I of K (items I, I+K, ...) into --out and stop; a job array "
        "runs the K shards into one folder, then a run without --shard collects",
    )


def _keep_results_arg(p: argparse._ActionsContainer) -> None:
    """Add ``--keep-results/--no-keep-results`` (``SweepOptions.keep_results``, default keep)."""
    p.add_argument(
        "--keep-results",
        action=argparse.BooleanOptionalAction,
        default=True,
        help="hold every start's result in memory (default); --no-keep-results holds only "
        "the best and the distinct optima, the other starts stay in the run folder "
        "(for 10^4+ starts; see docs/scaling.md)",
    )


def _loading_options(group: argparse._ActionsContainer) -> None:
    """Add ``--package-dir``, ``--lenient`` and ``--lock`` (how a named robot is loaded)."""
    group.add_argument(
        "--package-dir",
        action="append",
        default=[],
        metavar="DIR",
        help="folder for package:// mesh references (repeatable; example-robot-data's are "
        "found automatically)",
    )
    group.add_argument(
        "--lenient",
        action="store_true",
        help="load implausible inertias on moving links with a warning instead of refusing",
    )
    group.add_argument(
        "--lock",
        action="append",
        default=[],
        type=parse_lock,
        metavar="NAME=VALUE",
        help="lock a joint at a position in rad or m (repeatable)",
    )


def _robot_arguments(parser: argparse.ArgumentParser, *, default: str = "youbot") -> None:
    """Add ``--robot``, ``--package-dir``, ``--lenient``, ``--lock`` and ``--tip-frame``."""
    group = parser.add_argument_group("robot")
    group.add_argument(
        "--robot",
        default=default,
        metavar="NAME|PATH",
        help=f"robot name (`youbot-opt robots` lists them) or URDF path (default: {default})",
    )
    _loading_options(group)
    group.add_argument(
        "--tip-frame", default=None, metavar="F", help="end-effector frame (default: the robot's)"
    )
    load = parser.add_argument_group("payload (a rigid body fixed in a robot frame)")
    load.add_argument(
        "--payload-mass", type=float, default=None, metavar="KG", help="payload mass in [kg]"
    )
    load.add_argument(
        "--payload-com",
        type=float,
        nargs=3,
        default=None,
        metavar=("X", "Y", "Z"),
        help="its centre of mass in [m], in the payload frame (default: the frame's origin)",
    )
    load.add_argument(
        "--payload-inertia",
        type=float,
        nargs="+",
        default=None,
        metavar="I",
        help="its inertia about the centre of mass in [kg m^2], in the frame's axes: 3 "
        "principal moments, 6 values ixx ixy ixz iyy iyz izz, or 9 row by row (default 0: "
        "a point mass)",
    )
    load.add_argument(
        "--payload-frame",
        default=None,
        metavar="F",
        help="the frame carrying it (default: the tip frame)",
    )


def _ipopt_arguments(p: argparse.ArgumentParser) -> None:
    """IPOPT's iteration cap, Hessian and linear solver."""
    p.add_argument(
        "--max-iter",
        type=int_in_range("--max-iter", 0, MAX_ITER_LIMIT),
        default=3000,
        help="IPOPT iteration cap (default 3000)",
    )
    p.add_argument(
        "--hessian",
        choices=HESSIAN_NAMES,
        default="auto",
        help="IPOPT's Hessian of the Lagrangian: exact (the dynamics' second-derivative "
        "kernel) or limited-memory (L-BFGS: no such kernel, so far cheaper while the kernels "
        "run in CasADi's virtual machine, but more iterations once compiled, and it may "
        "reach another local optimum; docs/design.md, 'Exact or limited-memory'); default "
        "auto: exact where the backend has it",
    )
    p.add_argument(
        "--linear-solver",
        choices=LINEAR_SOLVER_NAMES,
        default="mumps",
        help="IPOPT's sparse linear solver (default mumps; HSL's ma27/ma57/... need "
        "--linear-solver-library)",
    )
    p.add_argument(
        "--linear-solver-library",
        default=None,
        metavar="PATH",
        help="the library IPOPT loads HSL's solvers (libhsl.so) or Pardiso from",
    )


def _refine_arguments(
    p: argparse.ArgumentParser,
    grid: str = "the grid of --knots",
    unrefined: str = "the plan is certified once on it, not refined",
) -> None:
    """Add the mesh-refinement options (on by default; ``--no-refine`` keeps the grid).

    ``grid`` names the starting grid in the help (``main`` has no ``--knots``),
    ``unrefined`` says what ``--no-refine`` does with the plan.
    """
    g = p.add_argument_group(
        "mesh refinement",
        f"by default {grid} is refined until every interval's collocation error "
        "is within --error-tol and the plan passes its certificate (or the budget runs out)",
    )
    g.add_argument(
        "--no-refine",
        dest="refine",
        action="store_false",
        help=f"keep {grid}: {unrefined}",
    )
    g.add_argument(
        "--error-tol",
        type=float,
        default=1e-3,
        help="largest relative collocation error of an interval (default 1e-3)",
    )
    g.add_argument("--max-rounds", type=int, default=8, help="refinement rounds (default 8)")
    g.add_argument("--max-knots", type=int, default=1000, help="largest grid (default 1000)")
    g.add_argument(
        "--refine-time",
        type=float,
        default=None,
        metavar="SECONDS",
        help="no new refinement round after this wall time [s] (default: no limit)",
    )
    g.add_argument(
        "--no-refine-fallback",
        dest="refine_fallback",
        action="store_false",
        help="keep Hermite-Simpson when its torque overshoots at a bang-bang switch (by "
        "default the next round re-solves the same knots with the trapezoidal scheme)",
    )


# ------------------------------------------------------------------ the commands
_Sub = argparse._SubParsersAction  # type: ignore[type-arg]


def _pair_arguments(p: argparse.ArgumentParser) -> None:
    """Add ``--srdf`` and ``--disable-pair`` (#28 item 2): which self-collision pairs count."""
    p.add_argument(
        "--srdf",
        type=Path,
        default=None,
        metavar="FILE",
        help="SRDF whose <disable_collisions> pairs are left out (default: the SRDF beside "
        "the URDF, if any)",
    )
    p.add_argument(
        "--disable-pair",
        nargs=2,
        action="append",
        default=None,
        metavar=("LINK_A", "LINK_B"),
        help="leave out the self-collision pairs of these two links (or geometries); repeatable",
    )


def _clearance_arguments(p: argparse.ArgumentParser, *, ends: bool = True) -> None:
    """Add ``--scene``, ``--margin``, ``--no-self-collision`` and the pair flags (#28).

    ``ends``: also ``--end-window`` (a trajectory's fixed ends; not the cyclic IK path's).
    """
    p.add_argument(
        "--scene",
        type=Path,
        default=None,
        metavar="FILE",
        help="obstacles (JSON scene file, docs/scene.md): the motion keeps --margin from them "
        "and from the robot itself at every knot and collocation point",
    )
    p.add_argument(
        "--margin",
        type=float,
        default=None,
        metavar="M",
        help="required clearance in [m] (default 0 with --scene; alone: self-collision only)",
    )
    p.add_argument(
        "--no-self-collision",
        action="store_true",
        help="with --scene: do not keep the robot's own links apart (the SRDF's active pairs)",
    )
    if ends:
        p.add_argument(
            "--end-window",
            type=float,
            default=None,
            metavar="F",
            help="fraction of the motion's duration (0 to 0.5) over which a pair whose bounding "
            "balls miss the margin at the start or goal must reach it (default 0.1; 0: such "
            "ends are refused; docs/scene.md)",
        )
    _pair_arguments(p)


def _tool_arguments(p: argparse.ArgumentParser) -> None:
    """Add the tool constraints of ``solve`` (#30, docs/tool.md): on the tip frame (--tip-frame)."""
    g = p.add_argument_group("tool constraints (on the --tip-frame; docs/tool.md)")
    g.add_argument(
        "--keep-axis",
        type=float,
        nargs=6,
        default=None,
        metavar=("AX", "AY", "AZ", "DX", "DY", "DZ"),
        help="keep the tool axis A (tool frame) within --max-tilt of the world direction D "
        "(a cup upright)",
    )
    g.add_argument(
        "--max-tilt",
        type=float,
        default=None,
        metavar="DEG",
        help="largest angle between the --keep-axis axis and direction, in DEGREES",
    )
    g.add_argument(
        "--line",
        type=float,
        nargs=6,
        default=None,
        metavar=("X0", "Y0", "Z0", "X1", "Y1", "Z1"),
        help="keep the tool point within --line-tol of the world segment P0-P1 [m] (a weld)",
    )
    g.add_argument(
        "--line-tol", type=float, default=None, metavar="M", help="distance to --line in [m]"
    )
    g.add_argument(
        "--tool-speed",
        type=float,
        default=None,
        metavar="M_PER_S",
        help="largest linear speed of the tool point in [m/s]",
    )


def _no_figures_argument(p: argparse._ActionsContainer, names: str = "*.png") -> None:
    """``--no-figures``: the command draws no figure (``names``); its other files are written."""
    p.add_argument(
        "--no-figures",
        action="store_true",
        help=f"write no figure ({names}); every other file of the run folder is written",
    )


def _main(sub: _Sub) -> None:
    p = sub.add_parser(
        "main",
        help="run the main job (the study-1 base case)",
        description="Solve the study-1 base case (beta = 0.5, trapezoidal, straight-line "
        "start) on the study's 50 knots, refine the grid until the plan is certified, and "
        "write the run folder. Other grids, robots and transcriptions: youbot-opt solve.",
    )
    p.add_argument(
        "--out",
        type=Path,
        default=None,
        metavar="DIR",
        help="output folder (default: a new youbot_opt_runs/main-<date>-<time>)",
    )
    _no_figures_argument(p)
    _refine_arguments(p, grid="the study's 50-knot grid")


def _solve(sub: _Sub) -> None:
    p = sub.add_parser(
        "solve",
        help="optimise a point-to-point trajectory (default: the study-1 youBot problem)",
        description="Solve the time/work trajectory problem f = beta T + (1 - beta) W by "
        "direct collocation with IPOPT.",
    )
    _robot_arguments(p)
    p.add_argument(
        "--start",
        type=float,
        nargs="+",
        metavar="Q",
        help="start joint positions [rad] (default for the youBot: the study's; required "
        "for any other robot)",
    )
    p.add_argument(
        "--goal",
        type=float,
        nargs="+",
        metavar="Q",
        help="goal joint positions [rad] (default for the youBot: the study's; required "
        "for any other robot)",
    )
    p.add_argument("--beta", type=float, default=0.5, help="time weight in [0, 1] (default 0.5)")
    p.add_argument("--knots", type=int, default=50, help="number of knots (default 50)")
    p.add_argument(
        "--transcription",
        choices=("trapezoidal", "hermite-simpson", "radau", "auto"),
        default=None,
        help="collocation scheme (default: trapezoidal for the study's youBot, as the study "
        f"did; {DEFAULT_TRANSCRIPTION} for any other robot: L-stable, so stiff joint damping "
        "and light links do not keep the refinement from certifying; auto picks radau when "
        "the damping is stiff on the grid, else hermite-simpson)",
    )
    p.add_argument(
        "--guess",
        choices=("straight", "spline"),
        default="straight",
        help="initial guess: straight line or the study's random feasible spline",
    )
    p.add_argument(
        "--seed",
        type=int_in_range("--seed", 0, SEED_LIMIT),
        default=0,
        help="seed of the spline guess(es) (default 0)",
    )
    p.add_argument(
        "--starts",
        type=int,
        default=1,
        help="number of random starts; > 1 runs a multistart (default 1), saved in "
        "--out DIR/starts as they finish: a rerun with the same --out resumes",
    )
    p.add_argument(
        "--workers",
        type=int,
        default=None,
        help="parallel starts with --starts > 1 (default: the CPUs available; 0: serial)",
    )
    p.add_argument("--quiet", action="store_true", help="no progress on stderr (implied by --json)")
    _scheduler_args(p, shard=False)  # the --starts > 1 multistart runs on Dask with them
    p.add_argument(
        "--bound-scale",
        type=float,
        default=1.0,
        help="scale of all bounds, 1.0 = data sheet (default 1.0)",
    )
    p.add_argument(
        "--damping",
        type=float,
        default=None,
        help="youBot joint damping [N m s/rad] (the study's code: 0.1; default 0)",
    )
    p.add_argument(
        "--backend",
        choices=("symbolic", "pinocchio"),
        default="symbolic",
        help="dynamics backend (default symbolic: exact Hessian)",
    )
    _ipopt_arguments(p)
    p.add_argument(
        "--out",
        type=lambda text: Path(out_arg(text)),
        default=None,
        metavar="DIR",
        help="output folder (default: a new youbot_opt_runs/solve-<date>-<time>)",
    )
    _no_figures_argument(p)
    p.add_argument("--json", action="store_true", help="print one JSON object on stdout")
    _clearance_arguments(p)
    _tool_arguments(p)
    _refine_arguments(p)
    timed = p.add_argument_group("through waypoints (docs/timed.md)")
    timed.add_argument(
        "--waypoints",
        metavar="FILE",
        help="pass through these configurations (CSV or JSON, rad) in order at free times, "
        "hermite-simpson unless --transcription; refined within the segments like any plan",
    )
    timed.add_argument(
        "--closed", action="store_true", help="with --waypoints: end back at the first one"
    )
    timed.add_argument(
        "--segment-knots",
        type=int,
        default=None,
        metavar="N",
        help="with --waypoints: knots of each segment, its ends included (default 20)",
    )


def _report(sub: _Sub) -> None:
    p = sub.add_parser(
        "report",
        help="print a model report: joints, masses, limits, M(q), gravity torques, tip pose",
        description="Print a model report of a robot at a configuration.",
    )
    _robot_arguments(p)
    p.add_argument(
        "--q",
        type=float,
        nargs="+",
        default=None,
        metavar="Q",
        help="configuration in [rad] (default: the study's start for youbot, else neutral)",
    )
    _pair_arguments(p)


_ROBOTS_EPILOG = """\
verdicts:
    default   loads as it is (what --robot NAME|PATH does)
    lenient   loads only with --lenient; the rule that needs it and its line follow
    refused   does not load even with --lenient; the rule and its line follow

exit status:
    0  every robot was surveyed, whatever its verdict (read the verdicts from
       the table, or "status" in --json)
    2  an argument is neither a robot name nor an existing file

examples:
    youbot-opt robots --names
    youbot-opt robots ur5 panda
    youbot-opt robots path/to/my_arm.urdf ur5 [--json]
"""


def _robots(sub: _Sub) -> None:
    p = sub.add_parser(
        "robots",
        help="whether robots load, by name or URDF path: dof, joint types, default or --lenient",
        description="Say whether robots load, each with a fixed base: the robots --robot "
        "accepts by name (youbot, youbot_arm_5dof and every URDF of the installed "
        "example-robot-data; all of them by default) and URDF files of your own, given by "
        "path. For each: nq/nv, the joint types of its file, and whether it loads by "
        "default, only with --lenient, or is refused (with the rule and its line).",
        epilog=_ROBOTS_EPILOG,
        formatter_class=argparse.RawDescriptionHelpFormatter,
    )
    p.add_argument(
        "names",
        nargs="*",
        metavar="NAME|PATH",
        help="robot names or URDF files to survey, mixed freely (default: every name); a "
        "known name is taken as the name",
    )
    p.add_argument("--names", dest="names_only", action="store_true", help="print names only")
    p.add_argument("--json", action="store_true", help="print one JSON list on stdout")
    p.add_argument("--out", default=None, metavar="FILE", help="also write the rows as JSON")


def _study_common(p: argparse.ArgumentParser) -> None:
    """Add the flags of every study-1 sweep (``multistart``, ``pareto``, ``bounds``)."""
    p.add_argument("--knots", type=int, default=50, help="collocation knots (default 50)")
    p.add_argument(
        "--seed",
        type=int_in_range("--seed", 0, SEED_LIMIT),
        default=0,
        help="base seed of the random starts (default 0)",
    )
    p.add_argument(
        "--workers",
        type=int,
        default=None,
        help="parallel worker processes (default: CPUs available; 0 = in-process)",
    )
    p.add_argument(
        "--out",
        type=out_arg,
        default=None,
        metavar="DIR",
        help="output folder (default: a new youbot_opt_runs/<command>-<date>-<time>); "
        "each finished item is saved there as it completes and rerunning resumes",
    )
    p.add_argument("--json", action="store_true", help="print one JSON summary on stdout")
    p.add_argument(
        "--transcription",
        default="trapezoidal",
        choices=("trapezoidal", "hermite-simpson", "radau", "auto"),
        help="collocation scheme (radau is L-stable, for stiff joint damping; auto picks "
        "radau when the damping is stiff on the grid, else hermite-simpson)",
    )
    p.add_argument(
        "--backend", default="symbolic", choices=("symbolic", "pinocchio"), help="dynamics backend"
    )
    _ipopt_arguments(p)
    p.add_argument(
        "--item-timeout",
        type=float,
        default=None,
        metavar="SECONDS",
        help="wall-clock limit per item attempt: a solve still running then is killed, "
        "recorded as failed and retried once (default: none; needs --workers >= 1)",
    )
    p.add_argument("--quiet", action="store_true", help="no progress on stderr")
    _no_figures_argument(p)
    _scheduler_args(p)
    _keep_results_arg(p)  # --no-keep-results: the starts stay in the folder (10^4+ starts)
    _refine_arguments(p, unrefined="the reported plans are neither refined nor certified")


def _studies(sub: _Sub) -> None:
    p = sub.add_parser(
        "multistart",
        help="seeded multistart of the study-1 problem",
        description="Solve study 1 from seeded random spline guesses.",
    )
    _study_common(p)
    p.add_argument("--starts", type=int, default=50, help="random spline starts (default 50)")
    p.add_argument("--beta", type=float, default=0.5, help="time weight in [0, 1]")
    p.add_argument("--bound-scale", type=float, default=1.0, help="bound scale (1 = data sheet)")
    p.add_argument("--straight", action="store_true", help="also start from the straight line")
    _clearance_arguments(p)
    p.add_argument(
        "--obj-tol",
        type=float_in_range("--obj-tol", 0.0, sys.float_info.max),
        default=1e-5,
        help="relative objective tolerance of the distinct-optima clustering (> 0; default 1e-5)",
    )
    p.add_argument(
        "--dist-tol",
        type=float_in_range("--dist-tol", 0.0, sys.float_info.max),
        default=1e-2,
        help="trajectory distance tolerance in [rad] of the clustering (> 0; default 1e-2)",
    )

    p = sub.add_parser(
        "pareto",
        help="warm-started weighted-sum Pareto sweep",
        description="Sweep beta, each solve warm-started from the previous.",
    )
    _study_common(p)
    p.add_argument("--betas", default="0.05:0.95:0.05", help="'start:stop:step' or 'a,b,c'")
    p.add_argument("--bound-scale", type=float, default=1.0, help="bound scale (1 = data sheet)")
    p.add_argument(
        "--first-starts",
        type=int,
        default=0,
        help="seeded starts at the first beta (default 0: straight line only)",
    )
    _clearance_arguments(p)

    p = sub.add_parser(
        "bounds",
        help="bound-scaling sensitivity study",
        description="Re-solve with all bounds scaled by each factor.",
    )
    _study_common(p)
    p.add_argument("--scales", default="1,0.95,0.9,0.85", help="'a,b,c' or 'start:stop:step'")
    p.add_argument("--beta", type=float, default=0.5, help="time weight in [0, 1]")
    p.add_argument("--starts", type=int, default=5, help="random starts per scale (default 5)")


def _reproduce(sub: _Sub) -> None:
    p = sub.add_parser(
        "reproduce-study1",
        help="reproduce study 1 (its transcription and the correct ones), certified",
        description="Reproduce study 1 with the study's own transcription and the correct "
        "ones; write JSON and markdown tables.",
    )
    p.add_argument("--quick", action="store_true",
                   help="a fast subset (3 base-case starts, 2 search starts)")  # fmt: skip
    p.add_argument("--out", default=None, metavar="DIR",
                   help="output folder (default: new, under youbot_opt_runs/)")  # fmt: skip
    p.add_argument("--search-starts", type=int, default=None, metavar="K",
                   help="second-optimum search starts (default: 200, quick: 2)")  # fmt: skip
    p.add_argument("--starts", type=int, default=None, metavar="K",
                   help="spline starts of the base case (default: 50, quick: 3)")  # fmt: skip
    p.add_argument("--seed", type=int, default=0, help="base seed of every multistart")
    p.add_argument("--workers", type=int, default=None, help="parallel starts (default: CPUs)")
    p.add_argument("--serial", action="store_true", help="run starts in this process")
    p.add_argument("--from-json", default=None, metavar="FILE",
                   help="rebuild the tables from a saved JSON file, without solving")  # fmt: skip
    _no_figures_argument(p, "repro_*.png")


IKPATH_DESCRIPTION = """\
youbot-opt ikpath: minimum-motion cyclic joint path through targets (study 2).

    youbot-opt ikpath --example A --starts 200
    youbot-opt ikpath --example B --method ipopt --starts 200 --json
    youbot-opt ikpath --lengths 3 2 2 --limit 1.5708 --target 0 7 --target 5 0 --method ipopt
    youbot-opt ikpath --robot youbot --target 0.3 0.3 --target 0.1 0.5 --target 0.35 0.1
    youbot-opt ikpath --robot ur5 --target 0.4 0.2 0.3 --target 0.3 -0.3 0.4 --target 0.5 0 0.2

Targets X Y [m] are planar (--example, --lengths, --robot youbot); X Y Z, X Y Z AX AY AZ
(approach of the frame's z axis), X Y Z QX QY QZ QW (pose) or --targets FILE are spatial
(any --robot NAME|PATH, --tip-frame). Exit 0: best start succeeded; 1: failed; 2: unreachable
target. Starts are saved in --out DIR as they finish; a rerun resumes. Details: docs/ikpath.md.
"""


#: ``ikpath``'s default ``--time-budget`` [s]: ikpath.starts.AUTOMATIC_TIME_BUDGET (a test checks).
AUTOMATIC_TIME_BUDGET_S = 20.0


def _ikpath(sub: _Sub) -> None:
    p = sub.add_parser(
        "ikpath",
        help="minimum-motion cyclic IK path through tip targets (study 2)",
        description=IKPATH_DESCRIPTION,
        formatter_class=argparse.RawDescriptionHelpFormatter,
    )
    src = p.add_argument_group("arm and targets")
    src.add_argument("--example", choices=EXAMPLE_NAMES, help="the study's example A or B")
    src.add_argument(
        "--robot",
        metavar="NAME|PATH",
        help="youbot (planar, targets: platform x z), or a robot name (ur5, panda, ...) or "
        "URDF path for spatial targets",
    )
    src.add_argument("--tip-frame", metavar="F", help="spatial: the frame that visits the targets")
    src.add_argument("--frame", action=_Renamed, use="--tip-frame F")
    _loading_options(src)
    src.add_argument(
        "--targets",
        metavar="FILE",
        dest="targets_file",
        help="spatial: targets from a CSV or JSON file (see above)",
    )
    src.add_argument(
        "--tol", type=float, default=1e-6, help="spatial: position tolerance [m] (default 1e-6)"
    )
    src.add_argument(
        "--orientation-tol",
        type=float,
        default=1e-6,
        help="spatial: orientation tolerance [rad] (default 1e-6)",
    )
    src.add_argument("--lengths", type=float, nargs="+", metavar="L", help="link lengths [m]")
    src.add_argument(
        "--target",
        type=float,
        nargs="+",
        action="append",
        metavar="X",
        help="a target (repeat, in visiting order): X Y [m] (planar), X Y Z, X Y Z AX AY AZ "
        "or X Y Z QX QY QZ QW (spatial)",
    )
    lim = p.add_argument_group("joint limits [rad]")
    lim.add_argument("--limit", type=float, metavar="C", help="symmetric limits |q_i| <= C")
    lim.add_argument("--lower", type=float, nargs="+", metavar="L", help="lower limit(s)")
    lim.add_argument("--upper", type=float, nargs="+", metavar="U", help="upper limit(s)")
    lim.add_argument("--no-limits", action="store_true", help="ignore the arm's joint limits")
    lim.add_argument(
        "--reach-evaluations",
        type=int,
        default=None,
        metavar="N",
        help="budget of the reachability test: planar, evaluations of the branch and bound "
        f"(3+ links; default {PLANAR_REACH_EVALUATIONS}); spatial, boxes of the interval "
        f"search per target (default {SPATIAL_REACH_BOXES}, within its "
        f"{SPATIAL_REACH_SECONDS:g} s per target)",
    )
    run = p.add_argument_group("solver")
    run.add_argument(
        "--method",
        choices=METHOD_NAMES,
        default=None,
        help="al or ipopt (default: al for planar targets, ipopt for spatial ones)",
    )
    run.add_argument(
        "--starts",
        type=int,
        default=None,
        help="number of starts (default: automatic, the zero or greedy start, the targets' "
        "witnesses and the cheapest coherent IK branches, at most 2 s n within [16, 64]; "
        "1: the zero vector or the greedy path only)",
    )
    run.add_argument("--seed", type=int, default=0, help="seed of the random starts")
    run.add_argument(
        "--start-kind",
        choices=(*START_KIND_NAMES, *SPATIAL_START_KIND_NAMES, "branches"),
        default=None,
        help="random starts: feasible (default for a planar robot) or uniform (planar); mixed "
        "(default for other robots), coherent, random or, for a planar robot, feasible "
        "(spatial); branches (both, the default without --starts): witnesses and coherent "
        "IK branches first",
    )
    run.add_argument(
        "--workers",
        type=int,
        default=None,
        help="worker processes (default: the CPUs, 1 below 8 starts)",
    )
    _scheduler_args(run)  # --starts > 1 on a Dask cluster
    run.add_argument(
        "--max-wall-time",
        type=float,
        default=None,
        metavar="S",
        help="wall-time limit of each start's solve [s] (status max_time when reached)",
    )
    run.add_argument(
        "--time-budget",
        type=float,
        default=None,
        metavar="S",
        help="automatic starts (no --starts): begin no new start S s after they are "
        f"drawn (default {AUTOMATIC_TIME_BUDGET_S:g}); running starts finish, "
        "and a rerun with --out DIR goes on with the others",
    )
    out = p.add_argument_group("output")
    out.add_argument(
        "--out",
        metavar="DIR",
        help="run folder (default: a new youbot_opt_runs/ikpath-<UTC time> in the cwd)",
    )
    out.add_argument(
        "--segment-time",
        type=float_in_range("--segment-time", 0.0, MAX_SEGMENT_TIME),
        default=1.0,
        metavar="S",
        help=f"replay: duration of each move between targets [s], in (0, {MAX_SEGMENT_TIME:g}] "
        "(default 1)",
    )
    out.add_argument("--no-replay", action="store_true", help="do not write replay.html")
    _no_figures_argument(out, "ikpath_*.png")
    _keep_results_arg(out)
    out.add_argument("--json", action="store_true", help="print one JSON object")
    out.add_argument("--no-progress", action="store_true", help="no progress on stderr")
    out.add_argument(
        "--timed",
        action="store_true",
        help="then time the path: a closed cycle through its configurations from the first, "
        "at rest, at free times (needs masses: --robot youbot or a URDF robot; docs/timed.md)",
    )
    out.add_argument(
        "--segment-knots",
        type=int,
        default=None,
        metavar="N",
        help="with --timed: knots of each segment, its ends included (default 20)",
    )
    _clearance_arguments(p, ends=False)  # 3-D robots, both methods (docs/ikpath.md)
    _refine_arguments(p, grid="with --timed, the timed plan's grid")


#: What adds each command to the parser, in ``--help`` order (``_studies``: three).
_EXPORT_EPILOG = """\
formats (docs/export.md):
    csv      a header row "time [s],<joint>.q [rad],...,<joint>.tau [N m]", then one row a sample
    json     youbot_opt.trajectory_samples: time, q, v, a, tau, joint names and units
    ros2     a trajectory_msgs/JointTrajectory message (JSON, also the YAML `ros2 topic pub` reads)
    rosbag   a rosbag2 folder holding that message (needs `pip install youbot_opt[ros2]`)

examples (RUN_FOLDER: the run folder a solve wrote):
    youbot-opt export runs/ur5 --format csv --rate 500   [runs/ur5: the run folder of a solve]
    youbot-opt export runs/ur5/result.npz --format rosbag --topic /arm/joint_trajectory   [idem]
"""


def _export(sub: _Sub) -> None:
    p = sub.add_parser(
        "export",
        help="a run's plan sampled at a controller's rate, as CSV, JSON or ROS 2",
        description="Sample a saved plan at a controller's rate with its transcription's own "
        "interpolation (positions, velocities, accelerations, torques) and write it for a "
        "controller. The result is re-checked against its robot model when loaded.",
        epilog=_EXPORT_EPILOG,
        formatter_class=argparse.RawDescriptionHelpFormatter,
    )
    p.add_argument(
        "run", metavar="RUN_FOLDER", help="a run folder holding result.npz, or a result file"
    )
    p.add_argument(
        "--format", choices=("csv", "json", "ros2", "rosbag"), default="csv", help="(default csv)"
    )
    p.add_argument(
        "--rate", type=float, default=100.0, metavar="HZ", help="sample rate in [Hz] (default 100)"
    )
    p.add_argument(
        "--out",
        type=out_arg,
        default=None,
        metavar="PATH",
        help="output file or folder (default: trajectory_<rate>hz<suffix> beside the result)",
    )
    p.add_argument(
        "--topic",
        default=None,
        metavar="TOPIC",
        help="the rosbag's topic (default /joint_trajectory)",
    )
    p.add_argument(
        "--allow-failed",
        action="store_true",
        help="export a result whose re-check on load failed (it is refused by default)",
    )


_ADDERS: tuple[Callable[[_Sub], None], ...] = (
    _main, _solve, _report, _robots, _studies, _reproduce, _ikpath, _export,
)  # fmt: skip


def build_parser() -> argparse.ArgumentParser:
    """Build the top-level argument parser with every command of :data:`COMMANDS`.

    Returns
    -------
    argparse.ArgumentParser
        The parser; ``args.command`` names the chosen command.
    """
    parser = _Parser(
        prog="youbot-opt",
        description="Trajectory and IK-path optimisation of rigid-body arms (Pinocchio + CasADi).",
    )
    parser.add_argument("--version", action="version", version=f"youbot_opt {__version__}")
    sub = parser.add_subparsers(dest="command", metavar="COMMAND")
    for add in _ADDERS:
        add(sub)
    return parser


def parse(argv: Sequence[str]) -> argparse.Namespace:
    """Parse a command line (without the program name); no command is ``main``.

    Raises
    ------
    SystemExit
        On ``--help``, ``--version`` or an argument error (exit code 2), as argparse does.
    """
    argv = list(argv)
    if not argv or argv[0].startswith("-") and argv[0] not in ("-h", "--help", "--version"):
        argv = [DEFAULT_COMMAND, *argv]
    _ARGV[:] = argv
    return build_parser().parse_args(argv)

"""``youbot-opt robots``: whether robots, by name or URDF path, load; dof, joint types, status.

Each robot (``youbot``, ``youbot_arm_5dof``, every URDF of example-robot-data,
:func:`youbot_opt.robot.catalogue.available_robots`, or a URDF file of the
user's own) is loaded by default, then with ``--lenient``; the table gives
``nq``/``nv``, joint types and whether and how it loads (with the rule it
breaks and the line).

Usage::

    youbot-opt robots [NAME|PATH ...] [--names] [--json] [--out FILE]
"""

from __future__ import annotations

import argparse
import json
import sys
import warnings
from collections import Counter
from dataclasses import asdict, dataclass
from pathlib import Path

from youbot_opt._files import atomic_write_text
from youbot_opt.exceptions import ModelError, RobotNotFound, URDFError, YoubotOptWarning
from youbot_opt.robot.catalogue import available_robots, find_robot
from youbot_opt.robot.load import load_model
from youbot_opt.robot.urdf_check.xml import parse_xml_strict, root_of

__all__ = ["RobotSurvey", "run", "survey"]


@dataclass(frozen=True, slots=True, kw_only=True)
class RobotSurvey:
    """What loading one robot gave.

    Attributes
    ----------
    name : str
        Robot name.
    path : str
        Its URDF file.
    status : str
        ``"default"`` (loads), ``"lenient"`` (loads with ``strict=False`` only)
        or ``"refused"``.
    nq, nv : int or None
        Configuration and velocity sizes of the fixed-base model (None if refused).
    joint_types : str
        Movable joints of the file by URDF type, e.g. ``"revolute 6, prismatic 2"``.
    warnings : int
        Implausible-inertia warnings of the load that succeeded (other warnings,
        e.g. about meshes, are not counted).
    reason : str
        Why the default load failed (the rule, the element and its line); for
        ``"refused"`` why the lenient load failed too; else ``""``.
    message : str
        The full error message of the default load (of the lenient load for
        ``"refused"``), else ``""``.
    """

    name: str
    path: str
    status: str
    nq: int | None
    nv: int | None
    joint_types: str
    warnings: int
    reason: str
    message: str


def _joint_types(path: Path) -> str:

    try:
        root = root_of(parse_xml_strict(path.read_bytes(), str(path)), str(path))
    except (URDFError, OSError):
        return "?"
    counts = Counter(
        j.get("type", "?") for j in root.iter("joint") if j.get("type", "fixed") != "fixed"
    )
    return ", ".join(f"{t} {n}" for t, n in sorted(counts.items())) or "none"


def _reason(exc: Exception, urdf: Path) -> str:
    """Return the rule, the element and where it is (``line N``, or a mesh's file and line)."""
    if not isinstance(exc, URDFError) or not exc.rule:
        return str(exc).splitlines()[0]
    where = [] if exc.element is None else [str(exc.element)]
    if exc.line is not None:
        other = exc.path is not None and Path(exc.path).resolve() != urdf.resolve()
        where.append(f"{exc.path}:{exc.line}" if other else f"line {exc.line}")
    return f"{exc.rule} (at {', '.join(where)})" if where else exc.rule


def survey(name: str) -> RobotSurvey:
    """Load ``name`` by default, then leniently, and say what happened.

    Parameters
    ----------
    name : str
        A name of :func:`youbot_opt.robot.catalogue.available_robots` or a URDF path.

    Returns
    -------
    RobotSurvey
        Status, sizes, joint types and the reason of a refusal.
    """
    entry = find_robot(name)
    path = entry.urdf_path if entry is not None else Path(name).resolve()
    reason = message = ""
    robot = None
    status = "refused"
    caught: list[warnings.WarningMessage] = []
    for strict in (True, False):
        with warnings.catch_warnings(record=True) as record:
            warnings.simplefilter("always", YoubotOptWarning)
            try:
                robot = load_model(name, strict=strict)
            except ModelError as exc:  # refused leniently too: say what refuses it then
                message, reason = str(exc), _reason(exc, path)
                continue
        status, caught = ("default" if strict else "lenient"), list(record)
        break
    count = sum(  # the inertia policy's warnings (meshes may warn too)
        issubclass(w.category, YoubotOptWarning) and "<inertia> of link" in str(w.message)
        for w in caught
    )
    count = count if robot is not None else 0
    if robot is not None and robot.urdf_path is not None:
        path = robot.urdf_path
    return RobotSurvey(
        name=name,
        path=str(path),
        status=status,
        nq=None if robot is None else robot.nq,
        nv=None if robot is None else robot.nv,
        joint_types=_joint_types(Path(path)),
        warnings=count,
        reason=reason,
        message=message,
    )


def _is_file(text: str) -> bool:
    try:
        return Path(text).is_file()
    except OSError:  # e.g. a name longer than the file system allows
        return False


def run(args: argparse.Namespace) -> int:
    """Run ``youbot-opt robots``; returns the exit code."""
    known = available_robots()
    names = list(args.names) or list(known)
    unknown = [n for n in names if n not in known and not _is_file(n)]
    if unknown:
        raise RobotNotFound(
            f"neither a robot name nor an existing file: {unknown}; `youbot-opt robots "
            "--names` lists the names",
            available=known,
        )
    if args.names_only:
        print("\n".join(names))
        if args.out:
            atomic_write_text(args.out, json.dumps(names, indent=1) + "\n")
        return 0
    rows = []
    for i, name in enumerate(names, 1):
        if not args.json and len(names) > 3:
            print(f"[{i}/{len(names)}] loading {name}", file=sys.stderr, flush=True)
        rows.append(survey(name))
    if args.out:
        atomic_write_text(args.out, json.dumps([asdict(r) for r in rows], indent=1) + "\n")
    if args.json:
        print(json.dumps([asdict(r) for r in rows], indent=1))
        return 0
    width = max(len(r.name) for r in rows)
    print(f"{'robot':<{width}}  {'nq/nv':>7}  {'loads':<8}  joint types / why not")
    for r in rows:
        dof = f"{r.nq}/{r.nv}" if r.nq is not None else "-"
        note = r.joint_types
        if r.status == "lenient":
            note += f"; refused by default: {r.reason}"
        elif r.status == "refused":
            note += f"; refused, also with --lenient: {r.reason}"
        if r.warnings:
            note += f"; {r.warnings} inertia warning(s)"
        print(f"{r.name:<{width}}  {dof:>7}  {r.status:<8}  {note}")
    counts = Counter(r.status for r in rows)
    print(
        f"{len(rows)} robots: {counts['default']} load by default, {counts['lenient']} only "
        f"with --lenient, {counts['refused']} refused"
    )
    return 0

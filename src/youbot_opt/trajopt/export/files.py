"""Samples as plain files: CSV with a unit header, and JSON with the package's schema header.

CSV: one header row ``time [s],<joint>.q [rad],...,<joint>.v [rad/s],...,
<joint>.a [rad/s^2],...,<joint>.tau [N m]`` (units per joint kind, m for a
prismatic joint), then one row per sample, every number written with 17
significant digits so that it reads back bit for bit. JSON: schema
``youbot_opt.trajectory_samples`` (:data:`SCHEMA_VERSION`) with the SHA-256 of
its body (:func:`youbot_opt._files.schema_header`). Writes are atomic.

>>> write_csv(result.sample(500.0), "plan.csv")  # doctest: +SKIP
"""

from __future__ import annotations

import csv
import io
import json
import os
from pathlib import Path
from typing import Any

import numpy as np

from youbot_opt._files import (
    atomic_write_text,
    check_schema_header,
    json_digest,
    json_ready,
    schema_header,
)
from youbot_opt.exceptions import ResultFileError, YoubotOptError
from youbot_opt.robot.model import PRISMATIC_UNITS, REVOLUTE_UNITS, JointUnits
from youbot_opt.trajopt.export.samples import SampledTrajectory, acceleration_unit

__all__ = [
    "SCHEMA",
    "SCHEMA_VERSION",
    "read_csv",
    "read_json",
    "read_json_document",
    "writable_target",
    "write_csv",
    "write_json",
]

SCHEMA = "youbot_opt.trajectory_samples"
SCHEMA_VERSION = 1
_FIELDS = ("q", "v", "a", "tau")


def _unit(units: JointUnits, field: str) -> str:
    return {
        "q": units.position,
        "v": units.velocity,
        "a": acceleration_unit(units),
        "tau": units.effort,
    }[field]


def _units_from(position: str) -> JointUnits:
    return PRISMATIC_UNITS if position == "m" else REVOLUTE_UNITS


def writable_target(path: str | os.PathLike[str]) -> Path:
    """Return ``path`` as a Path whose folder exists, else raise ResultFileError naming it."""
    target = Path(path)
    if not target.parent.is_dir():
        raise ResultFileError(f"cannot write {target}: directory {target.parent} does not exist")
    return target


def read_json_document(path: str | os.PathLike[str]) -> object:
    """Return the parsed JSON of the file at ``path``.

    Parameters
    ----------
    path : str or path-like
        The JSON file (UTF-8).

    Returns
    -------
    object
        The document: a dict, list, str, int, float, bool or None.

    Raises
    ------
    ResultFileError
        ``cannot read <path>: <reason>`` if the file is missing or unreadable,
        not UTF-8, or not JSON.
    """
    try:
        return json.loads(Path(path).read_text(encoding="utf-8"))
    except (OSError, UnicodeDecodeError, json.JSONDecodeError) as exc:
        raise ResultFileError(f"cannot read {path}: {exc}") from exc


def write_csv(samples: SampledTrajectory, path: str | os.PathLike[str]) -> Path:
    """Write ``samples`` as CSV with a header naming each joint and unit.

    Parameters
    ----------
    samples : SampledTrajectory
        The samples.
    path : str or path-like
        Target file; its folder must exist.

    Returns
    -------
    Path
        The file written.

    Raises
    ------
    ResultFileError
        If the folder does not exist.
    """
    target = writable_target(path)
    header = ["time [s]"]
    for field in _FIELDS:
        header += [
            f"{name}.{field} [{_unit(u, field)}]"
            for name, u in zip(samples.joint_names, samples.units, strict=True)
        ]
    table = np.column_stack([samples.time, samples.q, samples.v, samples.a, samples.tau])
    buffer = io.StringIO()
    writer = csv.writer(buffer, lineterminator="\n")
    writer.writerow(header)
    writer.writerows([[f"{x:.17g}" for x in row] for row in table])
    atomic_write_text(target, buffer.getvalue())
    return target


def _parse_column(label: str, source: str) -> tuple[str, str, str]:
    """``"<joint>.<field> [<unit>]"`` -> (joint, field, unit)."""
    head, sep, unit = label.rpartition(" [")
    joint, dot, field = head.rpartition(".")
    if not sep or not unit.endswith("]") or not dot or field not in _FIELDS:
        raise ResultFileError(f"{source}: column {label!r} is not '<joint>.<q|v|a|tau> [<unit>]'")
    return joint, field, unit[:-1]


def read_csv(path: str | os.PathLike[str]) -> SampledTrajectory:
    """Read samples written by :func:`write_csv`.

    The rate is ``1 / (time[1] - time[0])``; the robot and interpolation names,
    which the CSV does not hold, are empty.

    Parameters
    ----------
    path : str or path-like
        The CSV file.

    Returns
    -------
    SampledTrajectory
        The samples.

    Raises
    ------
    ResultFileError
        If the file is missing or its header or rows are not as written.
    """
    source = str(path)
    try:
        with open(path, newline="", encoding="utf-8") as handle:
            rows = list(csv.reader(handle))
    except OSError as exc:
        raise ResultFileError(f"cannot read {source}: {exc}") from exc
    if len(rows) < 3 or not rows[0] or rows[0][0] != "time [s]":
        raise ResultFileError(f"{source}: expected a 'time [s],...' header and >= 2 rows")
    columns = [_parse_column(label, source) for label in rows[0][1:]]
    nv = len(columns) // len(_FIELDS)
    if nv * len(_FIELDS) != len(columns) or nv == 0:
        raise ResultFileError(f"{source}: {len(columns)} joint columns, not 4 per joint")
    names = tuple(joint for joint, _, _ in columns[:nv])
    for i, (joint, field, _) in enumerate(columns):
        if joint != names[i % nv] or field != _FIELDS[i // nv]:
            raise ResultFileError(f"{source}: columns are not in the order q, v, a, tau per joint")
    try:
        table = np.array([[float(x) for x in row] for row in rows[1:]], dtype=float)
    except ValueError as exc:
        raise ResultFileError(f"{source}: a value is not a number ({exc})") from exc
    if table.shape[1:] != (1 + 4 * nv,):
        raise ResultFileError(f"{source}: rows do not have {1 + 4 * nv} values")
    units = tuple(_units_from(unit) for _, _, unit in columns[:nv])
    blocks = [table[:, 1 + i * nv : 1 + (i + 1) * nv] for i in range(len(_FIELDS))]
    try:
        return SampledTrajectory(
            time=table[:, 0],
            q=blocks[0],
            v=blocks[1],
            a=blocks[2],
            tau=blocks[3],
            joint_names=names,
            units=units,
            rate_hz=1.0 / float(table[1, 0] - table[0, 0]),
        )
    except YoubotOptError as exc:
        raise ResultFileError(f"{source}: {exc}") from exc


def _body(samples: SampledTrajectory) -> dict[str, Any]:
    return {
        "robot": samples.robot,
        "interpolation": samples.interpolation,
        "rate_hz": samples.rate_hz,
        "joint_names": list(samples.joint_names),
        "units": {field: [_unit(u, field) for u in samples.units] for field in _FIELDS},
        "time": samples.time.tolist(),
        **{field: getattr(samples, field).tolist() for field in _FIELDS},
    }


def write_json(samples: SampledTrajectory, path: str | os.PathLike[str]) -> Path:
    """Write ``samples`` as JSON: schema header, then the samples and their units.

    Parameters
    ----------
    samples : SampledTrajectory
        The samples.
    path : str or path-like
        Target file; its folder must exist.

    Returns
    -------
    Path
        The file written.

    Raises
    ------
    ResultFileError
        If the folder does not exist.
    """
    target = writable_target(path)
    body = json_ready(_body(samples))
    doc = {**schema_header(SCHEMA, SCHEMA_VERSION, sha256=json_digest(body)), "samples": body}
    atomic_write_text(target, json.dumps(doc, allow_nan=False) + "\n")
    return target


def read_json(path: str | os.PathLike[str]) -> SampledTrajectory:
    """Read samples written by :func:`write_json`, checking schema and checksum.

    Parameters
    ----------
    path : str or path-like
        The JSON file.

    Returns
    -------
    SampledTrajectory
        The samples, bit for bit as written.

    Raises
    ------
    ResultFileError
        If the file is missing, not JSON, of another schema or version, or its
        checksum does not match.
    """
    source = str(path)
    doc = read_json_document(path)
    check_schema_header(doc, schema=SCHEMA, supported=SCHEMA_VERSION, source=source)
    assert isinstance(doc, dict)  # check_schema_header raised otherwise
    body = doc.get("samples")
    if not isinstance(body, dict) or json_digest(body) != doc.get("sha256"):
        raise ResultFileError(f"{source}: checksum mismatch (corrupted or edited file)")
    try:
        return SampledTrajectory(
            time=body["time"],
            q=body["q"],
            v=body["v"],
            a=body["a"],
            tau=body["tau"],
            joint_names=tuple(body["joint_names"]),
            units=tuple(_units_from(unit) for unit in body["units"]["q"]),
            rate_hz=body["rate_hz"],
            robot=body["robot"],
            interpolation=body["interpolation"],
        )
    except (KeyError, TypeError, YoubotOptError) as exc:
        raise ResultFileError(f"{source}: malformed samples ({exc!r})") from exc

"""Waypoints: configurations a timed trajectory passes through, in order (#30 item 3).

A :class:`Waypoints` is a plain, immutable spec (no CasADi): ``k`` joint
configurations in [rad] ([m] for prismatic joints), in the order the motion
visits them, and whether the cycle closes back to the first one. They come from
a user (:func:`load_waypoints`, CSV or JSON, strict like the targets files) or
from a cyclic IK path (:meth:`Waypoints.from_configurations` on
``IKPathResult.configurations``). :meth:`Waypoints.check` refuses a set that
does not fit a robot (width, position limits), naming the row and the joint.
"""

from __future__ import annotations

import csv
import io
import json
import math
from dataclasses import dataclass
from pathlib import Path

import numpy as np
from numpy.typing import ArrayLike

from youbot_opt._files import read_input_text
from youbot_opt._typing import Array
from youbot_opt.exceptions import ParameterError
from youbot_opt.robot.model import JointBounds

__all__ = ["MAX_WAYPOINTS", "MAX_WAYPOINTS_FILE_BYTES", "Waypoints", "load_waypoints"]

MAX_WAYPOINTS = 1000
"""Most waypoints a file or a :class:`Waypoints` may hold."""
MAX_WAYPOINTS_FILE_BYTES = 1 << 20
"""Largest waypoints file read [bytes]."""


@dataclass(frozen=True, slots=True, kw_only=True)
class Waypoints:
    """Configurations a trajectory passes through, in order, at free times.

    Attributes
    ----------
    q : ndarray, shape (k, nq)
        The waypoint configurations in [rad] ([m] for prismatic joints), k >= 1,
        visited in row order after the start state.
    closed : bool
        Close the cycle: after the last waypoint, return to the first row and
        end there at rest (the cyclic IK path's loop). False (default): the
        motion ends at the problem's goal.
    """

    q: Array
    closed: bool = False

    def __post_init__(self) -> None:
        try:
            q = np.array(self.q, dtype=float)
        except (TypeError, ValueError) as exc:
            raise ParameterError(
                f"waypoints.q must be a (k, nq) array of numbers, got {self.q!r}",
                name="waypoints",
            ) from exc
        if q.ndim != 2 or q.shape[0] < 1 or q.shape[1] < 1:
            raise ParameterError(
                f"waypoints.q must have shape (k, nq) with k >= 1, got {q.shape}",
                name="waypoints",
                value=q.shape,
            )
        if q.shape[0] > MAX_WAYPOINTS:
            raise ParameterError(
                f"{q.shape[0]} waypoints, more than MAX_WAYPOINTS = {MAX_WAYPOINTS}",
                name="waypoints",
                value=q.shape[0],
            )
        bad = np.argwhere(~np.isfinite(q))
        if bad.size:
            row, col = (int(i) for i in bad[0])
            raise ParameterError(
                f"waypoint row {row + 1}: q[{col}] = {q[row, col]} is not finite",
                name="waypoints",
                value=row + 1,
            )
        if not isinstance(self.closed, bool | np.bool_):
            raise ParameterError(
                f"waypoints.closed must be a bool, got {self.closed!r}", name="waypoints"
            )
        q.setflags(write=False)
        object.__setattr__(self, "q", q)
        object.__setattr__(self, "closed", bool(self.closed))

    @property
    def count(self) -> int:
        """Number of waypoint rows ``k``."""
        return int(self.q.shape[0])

    @property
    def visits(self) -> Array:
        """The configurations in the order the motion reaches them, shape (k or k + 1, nq).

        A closed cycle ends where it began: the first row is repeated at the end.
        """
        return np.vstack([self.q, self.q[:1]]) if self.closed else np.array(self.q)

    @classmethod
    def from_configurations(cls, configurations: ArrayLike, *, closed: bool = True) -> Waypoints:
        """Waypoints from a cyclic IK path's configurations (``IKPathResult.configurations``).

        Parameters
        ----------
        configurations : array_like, shape (s, n)
            Joint configurations in [rad], in the path's order.
        closed : bool
            Close the cycle back to the first configuration (default True: the
            IK path is a loop).
        """
        return cls(q=np.asarray(configurations, dtype=float), closed=closed)

    def check(self, bounds: JointBounds, *, robot_name: str = "robot") -> None:
        """Refuse waypoints that do not fit a robot's width and position bounds.

        Parameters
        ----------
        bounds : JointBounds
            The (scaled) bounds the trajectory is held to
            (:meth:`TrajOptProblem.bounds <youbot_opt.trajopt.problem.TrajOptProblem.bounds>`).
        robot_name : str
            Named in the messages.

        Raises
        ------
        ParameterError
            Wrong width (nq), or a row outside the position bounds: the message
            names the row (1-based), the joint, the value and the bound.
        """
        nq = int(np.asarray(bounds.q_lower).size)
        if self.q.shape[1] != nq:
            raise ParameterError(
                f"waypoints.q must have {nq} columns (one per joint of {robot_name!r}), "
                f"got shape {self.q.shape}",
                name="waypoints",
                value=self.q.shape,
            )
        lo, hi = np.asarray(bounds.q_lower), np.asarray(bounds.q_upper)
        outside = (self.q < lo) | (self.q > hi)
        if outside.any():
            row, j = (int(i) for i in np.argwhere(outside)[0])
            raise ParameterError(
                f"waypoint row {row + 1}: q[{j}] = {self.q[row, j]:.6g} rad is outside the "
                f"position bounds [{lo[j]:.6g}, {hi[j]:.6g}] rad of {robot_name!r}",
                name="waypoints",
                value=row + 1,
            )


def _number(text: str, where: str) -> float:
    try:
        x = float(text)
    except ValueError:
        raise ParameterError(f"{where}: {text!r} is not a number", name="waypoints") from None
    if not math.isfinite(x):
        raise ParameterError(f"{where}: {text!r} is not finite", name="waypoints")
    return x


def load_waypoints(path: str | Path, *, closed: bool | None = None) -> Waypoints:
    """Read waypoints from a CSV or JSON file (by suffix).

    CSV: one configuration a row, one column a joint in [rad] ([m] for
    prismatic joints), every row the same width; a header row of names is
    allowed (recognised when its first cell is not a number). JSON: a list of
    rows, or ``{"q": [[...], ...], "closed": bool}``.

    Parameters
    ----------
    path : str or Path
        The file (``.csv`` or ``.json``), at most :data:`MAX_WAYPOINTS_FILE_BYTES`.
    closed : bool or None
        Close the cycle; None (default) takes the JSON's ``"closed"`` (False if
        absent, and for CSV).

    Raises
    ------
    ParameterError
        Unknown suffix; a missing, special or oversized file; not UTF-8; not
        JSON/CSV; a ragged row, a value that is not a finite number, an unknown
        JSON key (the message names the row and the column).
    """
    file = Path(path)
    text = read_input_text(
        file, max_bytes=MAX_WAYPOINTS_FILE_BYTES, what="a waypoints file", name="waypoints"
    )
    suffix = file.suffix.lower()
    file_closed = False
    rows: list[list[float]] = []
    if suffix == ".json":
        try:
            data = json.loads(text)
        except (json.JSONDecodeError, RecursionError) as exc:
            raise ParameterError(
                f"{file}: not valid JSON ({str(exc)[:200]})", name="waypoints", value=str(file)
            ) from exc
        if isinstance(data, dict):
            unknown = sorted(set(data) - {"q", "closed"})
            if unknown:
                raise ParameterError(
                    f"{file}: unknown key(s) {unknown}; expected 'q' and optional 'closed'",
                    name="waypoints",
                )
            file_closed = data.get("closed", False)
            if not isinstance(file_closed, bool):
                raise ParameterError(f"{file}: 'closed' must be true or false", name="waypoints")
            data = data.get("q")
        if not isinstance(data, list):
            raise ParameterError(
                f"{file}: expected a list of configurations or {{'q': [...]}}",
                name="waypoints",
                value=str(file),
            )
        for k, row in enumerate(data):
            where = f"{file.name} row {k + 1}"
            if not isinstance(row, list):
                raise ParameterError(f"{where}: expected a list of numbers", name="waypoints")
            values = []
            for j, x in enumerate(row):
                if isinstance(x, bool) or not isinstance(x, int | float):
                    raise ParameterError(
                        f"{where} column {j + 1}: {x!r} is not a number", name="waypoints"
                    )
                values.append(_number(repr(x), f"{where} column {j + 1}"))
            rows.append(values)
    elif suffix == ".csv":
        try:
            records = [r for r in csv.reader(io.StringIO(text)) if any(c.strip() for c in r)]
        except csv.Error as exc:
            raise ParameterError(f"{file}: not a CSV file ({exc})", name="waypoints") from exc
        first = 0
        if records:
            try:
                float(records[0][0])
            except ValueError:
                first = 1  # a header of joint names
        for k, rec in enumerate(records[first:], start=first):
            rows.append(
                [
                    _number(c.strip(), f"{file.name} row {k + 1} column {j + 1}")
                    for j, c in enumerate(rec)
                ]
            )
    else:
        raise ParameterError(
            f"waypoints file must end in .csv or .json, got {file.name!r}",
            name="waypoints",
            value=str(file),
        )
    if not rows:
        raise ParameterError(f"{file}: no waypoints", name="waypoints", value=str(file))
    if len(rows) > MAX_WAYPOINTS:
        raise ParameterError(
            f"{file}: {len(rows)} waypoints, more than MAX_WAYPOINTS = {MAX_WAYPOINTS}",
            name="waypoints",
        )
    for k, row in enumerate(rows):
        if len(row) != len(rows[0]):
            raise ParameterError(
                f"{file.name}: waypoint {k + 1} has {len(row)} values, the first has "
                f"{len(rows[0])}",
                name="waypoints",
                value=k + 1,
            )
    return Waypoints(q=np.array(rows), closed=file_closed if closed is None else closed)

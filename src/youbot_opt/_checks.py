"""Shared argument validators: each returns the checked value or raises ParameterError.

Owns the checks that the public functions and dataclasses repeat: a finite
real number, a positive one, a non-negative one, a number in [0, 1], an int
with a lower bound, an array of a given shape, a time limit, and the two
study parameters every solver takes (``beta``, ``bound_scale``). Every
message names the argument, what was expected and the value received; the
:class:`~youbot_opt.exceptions.ParameterError` carries ``name`` and ``value``.
Layer 0: imports nothing of youbot_opt but :mod:`youbot_opt.exceptions`.

    dt = check_positive(dt, "dt", unit="s")       # "dt must be finite and > 0 [s], got -1"
"""

from __future__ import annotations

import math
from collections.abc import Iterable
from typing import Any, Literal, SupportsFloat, SupportsIndex, SupportsInt

import numpy as np

from youbot_opt.exceptions import ParameterError

__all__ = [
    "MAX_BOUND_SCALE",
    "MAX_SHOWN_CHARS",
    "check_beta",
    "check_bound_scale",
    "check_end_window",
    "check_finite",
    "check_int",
    "check_nonnegative",
    "check_positive",
    "check_shape",
    "check_time_limit",
    "check_unit_interval",
    "iterable",
    "shown",
    "to_float",
    "to_int",
]

#: Most characters of a user's value an error message echoes; a longer value
#: is cut there and followed by its length, e.g. ``'xxx…' … (100000 characters)``.
MAX_SHOWN_CHARS = 200


def to_float(value: object) -> float:
    """``float(value)``, for a value read from a file: a TypeError as ``float``'s if it is none.

    Accepts what :class:`float` accepts (numbers, numpy scalars, numeric strings).
    """
    if isinstance(value, str | bytes | bytearray | SupportsFloat | SupportsIndex):
        return float(value)
    raise TypeError(
        f"float() argument must be a string or a real number, not {type(value).__name__!r}"
    )


def to_int(value: object) -> int:
    """``int(value)``, for a value read from a file: a TypeError as ``int``'s if it is none."""
    if isinstance(value, str | bytes | bytearray | SupportsInt | SupportsIndex):
        return int(value)
    raise TypeError(
        "int() argument must be a string, a bytes-like object or a real number, "
        f"not {type(value).__name__!r}"
    )


def iterable(value: object) -> Iterable[object]:
    """``value``, for a value read from a file: a TypeError as ``iter``'s if it is not iterable."""
    if isinstance(value, Iterable):
        return value
    raise TypeError(f"{type(value).__name__!r} object is not iterable")


def shown(value: Any) -> str:
    """``repr(value)`` for an error message, cut after :data:`MAX_SHOWN_CHARS` characters.

    A cut text ends in ``… (N characters)``, N being the length of the value
    (of a string) or of its repr (of anything else).
    """
    text = repr(value)
    if len(text) <= MAX_SHOWN_CHARS:
        return text
    n = len(value) if isinstance(value, str) else len(text)
    return f"{text[:MAX_SHOWN_CHARS]}… ({n} characters)"


def _real(value: Any, name: str, expected: str) -> float:
    """``float(value)``, or a ParameterError saying ``name must be <expected>``."""
    try:
        return float(value)
    except (TypeError, ValueError) as exc:
        raise ParameterError(
            f"{name} must be {expected}, got {shown(value)}", name=name, value=value
        ) from exc


def _unit(unit: str | None) -> str:
    return f" [{unit}]" if unit else ""


def _against_zero(
    value: Any, name: str, relation: Literal[">", ">="], *, unit: str | None, note: str
) -> float:
    """``float(value)`` if finite and ``> 0`` or ``>= 0`` (``relation``), else a ParameterError.

    The one text of :func:`check_positive` and :func:`check_nonnegative`:
    ``"<name> must be finite and <relation> 0 [<unit>]<note>, got <value>"``.
    """
    x = _real(value, name, f"a number {relation} 0")
    if not (math.isfinite(x) and (x > 0.0 if relation == ">" else x >= 0.0)):
        raise ParameterError(
            f"{name} must be finite and {relation} 0{_unit(unit)}{note}, got {shown(value)}",
            name=name,
            value=value,
        )
    return x


def _in_zero_to(value: Any, name: str, upper: float, *, note: str) -> float:
    """``float(value)`` if it lies in ``[0, upper]``, else a ParameterError.

    The one text of :func:`check_unit_interval` and :func:`check_end_window`:
    ``"<name> must be in [0, <upper>]<note>, got <value>"``.
    """
    x = _real(value, name, f"a number in [0, {upper:g}]")
    if not (math.isfinite(x) and 0.0 <= x <= upper):
        raise ParameterError(
            f"{name} must be in [0, {upper:g}]{note}, got {shown(value)}", name=name, value=value
        )
    return x


def check_finite(value: Any, name: str, *, unit: str | None = None) -> float:
    """Return ``value`` as a float after checking it is a finite real number.

    Parameters
    ----------
    value : Any
        Anything :class:`float` accepts (numbers, numpy scalars).
    name : str
        Argument name for the message.
    unit : str, optional
        Unit shown in brackets in the message, e.g. ``"s"``.

    Returns
    -------
    float
        The value.

    Raises
    ------
    ParameterError
        If ``value`` is not a real number or is NaN/inf.
    """
    x = _real(value, name, "a real number")
    if not math.isfinite(x):
        raise ParameterError(
            f"{name} must be finite{_unit(unit)}, got {shown(value)}", name=name, value=value
        )
    return x


def check_positive(value: Any, name: str, *, unit: str | None = None, note: str = "") -> float:
    """Return ``value`` as a float after checking it is finite and > 0.

    Parameters
    ----------
    value : Any
        Anything :class:`float` accepts.
    name : str
        Argument name for the message.
    unit : str, optional
        Unit shown in brackets in the message, e.g. ``"s"``.
    note : str
        Explanation appended to the range, e.g. ``" (1.0 = data sheet)"``.

    Returns
    -------
    float
        The value.

    Raises
    ------
    ParameterError
        ``"<name> must be finite and > 0 [<unit>]<note>, got <value>"`` otherwise.
    """
    return _against_zero(value, name, ">", unit=unit, note=note)


def check_nonnegative(value: Any, name: str, *, unit: str | None = None, note: str = "") -> float:
    """Return ``value`` as a float after checking it is finite and >= 0.

    Parameters
    ----------
    value : Any
        Anything :class:`float` accepts.
    name : str
        Argument name for the message.
    unit : str, optional
        Unit shown in brackets in the message.
    note : str
        Explanation appended to the range.

    Returns
    -------
    float
        The value.

    Raises
    ------
    ParameterError
        ``"<name> must be finite and >= 0 [<unit>]<note>, got <value>"`` otherwise.
    """
    return _against_zero(value, name, ">=", unit=unit, note=note)


def check_unit_interval(value: Any, name: str, *, note: str = "") -> float:
    """Return ``value`` as a float after checking it lies in [0, 1].

    Parameters
    ----------
    value : Any
        Anything :class:`float` accepts.
    name : str
        Argument name for the message.
    note : str
        Meaning of the end points, e.g. ``" (1 = time only, 0 = work only)"``.

    Returns
    -------
    float
        The value.

    Raises
    ------
    ParameterError
        If ``value`` is not a number, NaN, or outside [0, 1].
    """
    return _in_zero_to(value, name, 1.0, note=note)


def check_end_window(value: Any, name: str = "end_window") -> float:
    """Return ``value`` as a float after checking it lies in [0, 0.5].

    An end window: the fraction of a motion's (normalised) duration next to
    each fixed end over which a path constraint ramps up to its bound.

    Raises
    ------
    ParameterError
        If ``value`` is not a number, not finite, or outside [0, 0.5].
    """
    return _in_zero_to(value, name, 0.5, note=" (a fraction of the motion's duration at each end)")


def check_int(value: Any, name: str, *, minimum: int = 0) -> int:
    """Return ``value`` as an int after checking it is an integer >= ``minimum``.

    Python and numpy integers are accepted; ``bool``, floats (even ``2.0``)
    and strings are not.

    Parameters
    ----------
    value : Any
        The integer to check.
    name : str
        Argument name for the message.
    minimum : int
        Smallest accepted value (0 for counts and seeds, 1 for sizes).

    Returns
    -------
    int
        The value.

    Raises
    ------
    ParameterError
        ``"<name> must be an int >= <minimum>, got <value>"`` otherwise.
    """
    if isinstance(value, bool) or not isinstance(value, int | np.integer) or value < minimum:
        raise ParameterError(
            f"{name} must be an int >= {minimum}, got {shown(value)}", name=name, value=value
        )
    return int(value)


def check_shape(
    value: Any, shape: tuple[int | str, ...], name: str, *, finite: bool = True
) -> np.ndarray:
    """Return ``value`` as a new float array after checking its shape (and finiteness).

    Parameters
    ----------
    value : array_like
        The array to check.
    shape : tuple of int or str
        Expected shape; a ``str`` entry (``"n"``, ``"s"``) accepts any size on
        that axis and names it in the message.
    name : str
        Argument name for the message.
    finite : bool
        Also refuse NaN and inf entries.

    Returns
    -------
    ndarray
        ``np.array(value, dtype=float)`` (a copy, writeable).

    Raises
    ------
    ParameterError
        ``"<name> must have shape (<shape>), got <shape>"``, ``"<name> must be
        finite, got <values>"``, or if ``value`` is not numeric.
    """
    want = "(" + ", ".join(str(s) for s in shape) + ("," if len(shape) == 1 else "") + ")"
    try:
        arr = np.array(value, dtype=float)
    except (TypeError, ValueError) as exc:
        raise ParameterError(
            f"{name} must be a numeric array of shape {want}, got {shown(value)}",
            name=name,
            value=value,
        ) from exc
    if arr.ndim != len(shape) or any(
        isinstance(s, int) and n != s for s, n in zip(shape, arr.shape, strict=True)
    ):
        raise ParameterError(
            f"{name} must have shape {want}, got {arr.shape}", name=name, value=arr.shape
        )
    if finite and not np.all(np.isfinite(arr)):
        raise ParameterError(
            f"{name} must be finite, got {shown(arr.tolist())}", name=name, value=arr
        )
    return arr


def check_time_limit(value: object, name: str) -> float | None:
    """Return ``value`` unless it is neither None nor a finite time > 0 [s].

    Only ``int`` and ``float`` are accepted (not ``bool``, not strings).

    Parameters
    ----------
    value : object
        The limit to check, in [s] (None: no limit).
    name : str
        Qualified field name for the message, e.g. ``"ALOptions.max_wall_time"``;
        the error's ``name`` is its last component.

    Returns
    -------
    float or None
        The limit.

    Raises
    ------
    ParameterError
        ``"<name> must be None or a finite time > 0 [s], got <value>"`` otherwise.
    """
    if value is None:
        return None
    if (
        isinstance(value, (int, float))
        and not isinstance(value, bool)
        and math.isfinite(value)
        and value > 0
    ):
        return float(value)
    raise ParameterError(
        f"{name} must be None or a finite time > 0 [s], got {shown(value)}",
        name=name.rsplit(".", 1)[-1],
        value=value,
    )


def check_beta(beta: Any) -> float:
    """Validate a time weight ``beta`` of the objective ``beta T + (1 - beta) W``.

    Parameters
    ----------
    beta : float
        Weight of the duration term, in [0, 1] (dimensionless).

    Returns
    -------
    float
        ``beta`` as a float.

    Raises
    ------
    ParameterError
        If ``beta`` is not a finite number in [0, 1].
    """
    return check_unit_interval(beta, "beta", note=" (1 = time only, 0 = work only)")


MAX_BOUND_SCALE = 1e3
"""Largest factor on a robot's speed and torque limits (dimensionless).

The bound study scales the data sheet by 0.85-1; a thousandfold motor is no
longer the robot, and far larger factors overflow the NLP's bounds.
"""


def check_bound_scale(bound_scale: Any) -> float:
    """Validate a bound scale factor (1.0 = data sheet, in ``(0, MAX_BOUND_SCALE]``).

    Parameters
    ----------
    bound_scale : float
        Factor on the speed and torque limits (dimensionless).

    Returns
    -------
    float
        ``bound_scale`` as a float.

    Raises
    ------
    ParameterError
        If ``bound_scale`` is not a finite number in ``(0, MAX_BOUND_SCALE]``.
    """
    value = check_positive(bound_scale, "bound_scale", note=" (1.0 = data sheet)")
    if value > MAX_BOUND_SCALE:
        raise ParameterError(
            f"bound_scale must be at most MAX_BOUND_SCALE = {MAX_BOUND_SCALE:g} "
            f"(1.0 = data sheet), got {shown(bound_scale)}",
            name="bound_scale",
            value=bound_scale,
        )
    return value

"""youbot_opt._checks: each validator's accepted and refused values, and its message."""

from __future__ import annotations

import math

import numpy as np
import pytest

from youbot_opt._checks import (
    check_beta,
    check_bound_scale,
    check_end_window,
    check_finite,
    check_int,
    check_nonnegative,
    check_positive,
    check_shape,
    check_time_limit,
    check_unit_interval,
)
from youbot_opt.exceptions import ParameterError


def test_check_finite() -> None:
    """Finite reals pass as floats; NaN, inf and non-numbers are refused by name."""
    assert check_finite(np.int64(3), "x") == 3.0
    assert type(check_finite(-2, "x")) is float
    with pytest.raises(ParameterError, match=r"x must be finite \[m\], got nan") as info:
        check_finite(math.nan, "x", unit="m")
    assert info.value.name == "x" and math.isnan(info.value.value)
    with pytest.raises(ParameterError, match="x must be a real number, got 'a'"):
        check_finite("a", "x")


def test_check_positive() -> None:
    """> 0 and finite pass; 0, negatives, inf and non-numbers are refused."""
    assert check_positive(0.5, "dt") == 0.5
    for bad in (0.0, -1, math.inf, math.nan):
        with pytest.raises(ParameterError, match=r"dt must be finite and > 0 \[s\], got"):
            check_positive(bad, "dt", unit="s")
    with pytest.raises(ParameterError, match="dt must be a number > 0, got None"):
        check_positive(None, "dt")


def test_check_nonnegative() -> None:
    """>= 0 and finite pass (0 included); negatives and inf are refused."""
    assert check_nonnegative(0, "damping") == 0.0
    with pytest.raises(ParameterError, match=r"damping must be finite and >= 0 \(x\), got -0.1"):
        check_nonnegative(-0.1, "damping", note=" (x)")
    with pytest.raises(ParameterError, match="damping must be finite and >= 0, got inf"):
        check_nonnegative(math.inf, "damping")
    with pytest.raises(ParameterError, match="a number >= 0"):
        check_nonnegative([1], "damping")


def test_check_unit_interval() -> None:
    """[0, 1] passes, ends included; outside, NaN and non-numbers are refused."""
    assert check_unit_interval(0, "w") == 0.0 and check_unit_interval(1, "w") == 1.0
    for bad in (-1e-9, 1.0 + 1e-9, math.nan):
        with pytest.raises(ParameterError, match=r"w must be in \[0, 1\], got"):
            check_unit_interval(bad, "w")
    with pytest.raises(ParameterError, match=r"w must be a number in \[0, 1\], got 'x'"):
        check_unit_interval("x", "w")


def test_check_end_window() -> None:
    """[0, 0.5] passes, ends included; outside, NaN and non-numbers are refused by name."""
    assert check_end_window(0) == 0.0 and check_end_window(0.5) == 0.5
    for bad in (-1e-9, 0.5 + 1e-9, math.nan):
        with pytest.raises(
            ParameterError,
            match=r"end_window must be in \[0, 0\.5\] \(a fraction of the motion's duration "
            r"at each end\), got",
        ):
            check_end_window(bad)
    with pytest.raises(ParameterError, match=r"w must be a number in \[0, 0\.5\], got 'x'"):
        check_end_window("x", "w")


@pytest.mark.parametrize("minimum", [0, 1])
def test_check_int(minimum: int) -> None:
    """Python and numpy ints >= minimum pass; bools, floats and smaller ints are refused."""
    assert check_int(np.int32(5), "n", minimum=minimum) == 5
    assert check_int(minimum, "n", minimum=minimum) == minimum
    for bad in (minimum - 1, True, 2.0, "3"):
        with pytest.raises(ParameterError, match=f"n must be an int >= {minimum}, got"):
            check_int(bad, "n", minimum=minimum)


def test_check_shape() -> None:
    """Exact and named axes; wrong rank, size, non-finite and non-numeric are refused."""
    arr = check_shape([[1, 2], [3, 4], [5, 6]], ("s", 2), "targets")
    assert arr.shape == (3, 2) and arr.dtype == float and arr.flags.writeable
    assert check_shape([1.0, np.nan], (2,), "q", finite=False).shape == (2,)
    with pytest.raises(ParameterError, match=r"targets must have shape \(s, 2\), got \(3,\)"):
        check_shape([1, 2, 3], ("s", 2), "targets")
    with pytest.raises(ParameterError, match=r"q must have shape \(3,\), got \(2,\)") as info:
        check_shape([1, 2], (3,), "q")
    assert info.value.value == (2,)
    with pytest.raises(ParameterError, match=r"q must be finite, got \[1.0, inf\]"):
        check_shape([1, math.inf], (2,), "q")
    with pytest.raises(ParameterError, match=r"q must be a numeric array of shape \(2,\)"):
        check_shape(["a", "b"], (2,), "q")


def test_check_time_limit() -> None:
    """None and finite times > 0 pass; bools, strings, 0, inf are refused with the field name."""
    assert check_time_limit(None, "Opts.max_wall_time") is None
    assert check_time_limit(2, "Opts.max_wall_time") == 2.0
    for bad in (0, -1.0, math.inf, True, "1"):
        with pytest.raises(
            ParameterError, match=r"Opts.max_wall_time must be None or a finite time > 0 \[s\]"
        ) as info:
            check_time_limit(bad, "Opts.max_wall_time")
        assert info.value.name == "max_wall_time"


def test_check_beta_and_bound_scale() -> None:
    """The two study parameters keep their explanatory messages."""
    assert check_beta(np.float64(0.5)) == 0.5
    with pytest.raises(ParameterError, match=r"beta must be in \[0, 1\] \(1 = time only"):
        check_beta(1.5)
    with pytest.raises(ParameterError, match=r"beta must be a number in \[0, 1\], got None"):
        check_beta(None)
    assert check_bound_scale(2) == 2.0
    with pytest.raises(ParameterError, match=r"bound_scale must be finite and > 0 \(1.0 = data"):
        check_bound_scale(0.0)
    with pytest.raises(ParameterError, match="bound_scale must be a number > 0, got 'x'") as info:
        check_bound_scale("x")
    assert info.value.name == "bound_scale"


def test_messages_cut_long_values():
    """A 100,000-character value is echoed cut to MAX_SHOWN_CHARS, with its length."""
    from youbot_opt._checks import MAX_SHOWN_CHARS

    for check in (check_finite, check_positive, check_nonnegative, check_unit_interval):
        with pytest.raises(ParameterError) as info:
            check("z" * 100_000, "x")
        assert len(str(info.value)) < MAX_SHOWN_CHARS + 100
        assert "(100000 characters)" in str(info.value)
    with pytest.raises(ParameterError) as info:
        check_int("z" * 100_000, "n")
    assert len(str(info.value)) < MAX_SHOWN_CHARS + 100
    with pytest.raises(ParameterError) as info:
        check_shape(["a"] * 10_000, (2,), "a")
    assert len(str(info.value)) < MAX_SHOWN_CHARS + 100

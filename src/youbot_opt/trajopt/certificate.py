"""The certificate of a plan: figures, tolerances, verdict (:mod:`youbot_opt.trajopt.certify`).

A :class:`Certificate` holds what :func:`youbot_opt.trajopt.certify.certify` measured
by forward simulation (local one-interval errors, PD tracking effort and
error, open-loop drift, bound excesses at and between knots);
:class:`Tolerances` holds the documented pass/fail thresholds, applied by
:meth:`Certificate.passed`, :attr:`Certificate.ok` and
:meth:`Certificate.failures`. :meth:`Certificate.summary` gives JSON-ready
numbers and ``str(certificate)`` a readable table.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from typing import Any, NamedTuple

import numpy as np

from youbot_opt._typing import Array
from youbot_opt.exceptions import ParameterError
from youbot_opt.trajopt.simulate import PDGains

__all__ = ["BoundCheck", "Certificate", "Tolerances"]

_QUANTITIES: tuple[tuple[str, str], ...] = (
    ("position", "rad"),
    ("velocity", "rad/s"),
    ("torque", "N m"),
)


_WHERE = {"knots": "at knots", "between": "between knots"}


@dataclass(frozen=True, slots=True, kw_only=True)
class Tolerances:
    """Pass/fail thresholds of a :class:`Certificate`.

    The defaults describe a plan the arm can follow to a few degrees without
    leaning on its feedback: every figure is an error the plan would leave for a
    controller to absorb.

    Attributes
    ----------
    local_position : float
        Largest one-interval position error in [rad] (0.05 rad, about 3 deg).
    local_velocity : float
        Largest one-interval velocity error in [rad/s] (0.5 rad/s, a third of
        the youBot's speed limit).
    feedback_rms : float
        Largest RMS feedback-to-planned torque ratio of any joint (5 %).
    feedback_peak : float
        Largest peak feedback-to-planned torque ratio of any joint (10 %).
    tracking_position : float
        Largest tracking position error in [rad] (0.05 rad).
    knot_bound : float
        Largest bound excess at the knots, relative to the bound's half range
        (``(upper - lower) / 2``; the bound itself for speed and torque). The
        default 1e-6 leaves room for the NLP solver's feasibility tolerance only.
    between_bound : float
        Largest bound excess between the knots, relative as above (1 %): the
        interpolants are O(h^2) approximations between knots and may overshoot
        a bound that is active at a knot.
    """

    local_position: float = 0.05  # [rad]
    local_velocity: float = 0.5  # [rad/s]
    feedback_rms: float = 0.05
    feedback_peak: float = 0.10
    tracking_position: float = 0.05  # [rad]
    knot_bound: float = 1e-6
    between_bound: float = 1e-2

    def __post_init__(self) -> None:
        for name in self.__dataclass_fields__:
            value = getattr(self, name)
            if not (isinstance(value, int | float) and value >= 0.0 and not math.isnan(value)):
                raise ParameterError(
                    f"tolerance {name} must be a number >= 0, got {value!r}", name=name, value=value
                )


class BoundCheck(NamedTuple):
    """Worst bound excess of one quantity, at the knots or between them.

    Attributes
    ----------
    quantity : str
        ``"position"``, ``"velocity"`` or ``"torque"``.
    where : str
        ``"knots"`` or ``"between"`` (interpolant samples strictly inside intervals).
    excess : float
        Largest ``value - upper`` or ``lower - value`` in [rad], [rad/s] or [N m];
        negative when the bound holds (then minus the smallest margin).
    relative : float
        ``excess`` divided by the bound's half range (dimensionless).
    time : float
        Time in [s] of the worst sample.
    joint : int
        Joint index (0-based) of the worst sample.
    """

    quantity: str
    where: str
    excess: float
    relative: float
    time: float
    joint: int


@dataclass(frozen=True, slots=True, kw_only=True)
class Certificate:
    """Figures of an independent forward-simulation check of a plan.

    Attributes
    ----------
    robot : str
        Robot name.
    n_knots : int
        Number of knots N.
    duration : float
        Plan duration in [s].
    interpolation : str
        The plan's interpolant (``"trapezoidal"`` or ``"hermite_simpson"``).
    local_position_error : ndarray, shape (N - 1,)
        Per interval, ``max_i |q_sim_i(t[k+1]) - q[k+1]_i|`` after restarting at
        knot k, in [rad].
    local_velocity_error : ndarray, shape (N - 1,)
        The same for velocities, in [rad/s].
    feedback_rms_ratio : ndarray, shape (nv,)
        Per joint, ``sqrt(int fb^2 dt / int tau_plan^2 dt)`` over the tracking
        simulation (dimensionless).
    feedback_peak_ratio : ndarray, shape (nv,)
        Per joint, ``max_t |fb| / max_t |tau_plan|`` (dimensionless).
    tracking_position_error : float
        Largest ``|q_sim - q_plan(t)|`` of the tracking simulation in [rad].
    tracking_velocity_error : float
        Largest ``|v_sim - v_plan(t)|`` of the tracking simulation in [rad/s].
    open_loop_final_error : float
        ``max_i |q_sim_i(T) - q[-1]_i|`` of the open-loop simulation in [rad];
        ``inf`` if it drifted by ``open_loop_stop`` before the end.
    open_loop_divergence_time : float
        Time in [s] (from the start) at which the open-loop simulation drifted by
        ``open_loop_stop``; ``inf`` if it never did.
    open_loop_stop : float
        Drift in [rad] at which the open-loop simulation is stopped.
    bounds : tuple of BoundCheck
        Worst bound excesses (see :func:`check_bounds`).
    gains : PDGains
        The tracking controller's gains.
    elapsed : float
        Wall time of :func:`certify` in [s].
    tolerances : Tolerances
        Thresholds used by :attr:`ok` (and by :meth:`passed` when given none).
    incomplete : str
        Why some figures were not measured (``certify``'s time limit ran out;
        they are NaN), or ``""``. An incomplete certificate never passes.
    """

    robot: str
    n_knots: int
    duration: float
    interpolation: str
    local_position_error: Array
    local_velocity_error: Array
    feedback_rms_ratio: Array
    feedback_peak_ratio: Array
    tracking_position_error: float
    tracking_velocity_error: float
    open_loop_final_error: float
    open_loop_divergence_time: float
    open_loop_stop: float
    bounds: tuple[BoundCheck, ...]
    gains: PDGains
    elapsed: float
    tolerances: Tolerances = field(default_factory=Tolerances)
    incomplete: str = ""

    # ------------------------------------------------------------ aggregates
    @property
    def local_position_max(self) -> float:
        """Largest one-interval position error in [rad]."""
        return float(np.max(self.local_position_error))

    @property
    def local_position_median(self) -> float:
        """Median one-interval position error in [rad]."""
        return float(np.median(self.local_position_error))

    @property
    def local_velocity_max(self) -> float:
        """Largest one-interval velocity error in [rad/s]."""
        return float(np.max(self.local_velocity_error))

    @property
    def local_velocity_median(self) -> float:
        """Median one-interval velocity error in [rad/s]."""
        return float(np.median(self.local_velocity_error))

    @property
    def worst_interval(self) -> int:
        """Index of the interval with the largest local position error."""
        return int(np.argmax(self.local_position_error))

    @property
    def feedback_rms(self) -> float:
        """Worst joint's RMS feedback-to-planned torque ratio."""
        return float(np.max(self.feedback_rms_ratio))

    @property
    def feedback_peak(self) -> float:
        """Worst joint's peak feedback-to-planned torque ratio."""
        return float(np.max(self.feedback_peak_ratio))

    def worst_bound(self, where: str) -> BoundCheck:
        """Return the check with the largest relative excess at ``"knots"`` or ``"between"``."""
        checks = [c for c in self.bounds if c.where == where]
        if not checks:
            raise ParameterError(
                f"where must be 'knots' or 'between', got {where!r}", name="where", value=where
            )
        return max(checks, key=lambda c: c.relative)

    # ------------------------------------------------------------- verdicts
    def _rows(self, tol: Tolerances) -> list[tuple[str, float, float, float, str]]:
        """(label, value, median or NaN, limit, note) of every tested figure."""
        nan = math.nan
        rows = [
            ("local error, position [rad]", self.local_position_max, self.local_position_median,
             tol.local_position, f"worst interval {self.worst_interval}"),
            ("local error, velocity [rad/s]", self.local_velocity_max,
             self.local_velocity_median, tol.local_velocity, ""),
            ("tracking: feedback/plan torque, RMS", self.feedback_rms, nan, tol.feedback_rms, ""),
            ("tracking: feedback/plan torque, peak", self.feedback_peak, nan, tol.feedback_peak,
             ""),
            ("tracking: position error [rad]", self.tracking_position_error, nan,
             tol.tracking_position, ""),
        ]  # fmt: skip
        for c in self.bounds:
            limit = tol.knot_bound if c.where == "knots" else tol.between_bound
            unit = dict(_QUANTITIES)[c.quantity]
            label = f"bound {c.quantity}, {_WHERE[c.where]} (relative)"
            note = f"excess {c.excess:.2e} {unit} at t = {c.time:.4g} s, joint {c.joint}"
            rows.append((label, c.relative, nan, limit, note))
        return rows

    def failures(self, tolerances: Tolerances | None = None) -> list[str]:
        """List each figure that exceeds its tolerance (empty if the plan passes).

        Parameters
        ----------
        tolerances : Tolerances, optional
            Thresholds; :attr:`tolerances` when omitted.

        Returns
        -------
        list of str
            One line per failed check. A NaN figure (failed integration) fails.
        """
        tol = self.tolerances if tolerances is None else tolerances
        incomplete = [f"incomplete: {self.incomplete}"] if self.incomplete else []
        return incomplete + [
            f"{label} = {value:.3g} > {limit:.3g}"
            for label, value, _, limit, _ in self._rows(tol)
            if not value <= limit
        ]

    def passed(self, tolerances: Tolerances | None = None) -> bool:
        """Return True if every figure is within ``tolerances`` (:attr:`tolerances` by default).

        The open-loop figures are reported, never tested.
        """
        return not self.failures(tolerances)

    @property
    def ok(self) -> bool:
        """:meth:`passed` with :attr:`tolerances`."""
        return self.passed()

    # -------------------------------------------------------------- reports
    def summary(self) -> dict[str, Any]:
        """JSON-ready figures (non-finite numbers become ``None``)."""

        def num(x: float) -> float | None:
            return float(x) if math.isfinite(x) else None

        out: dict[str, Any] = {
            "robot": self.robot,
            "n_knots": self.n_knots,
            "duration_s": num(self.duration),
            "interpolation": self.interpolation,
            "ok": self.ok,
            "worst_interval": self.worst_interval,
            "tracking_bandwidth_rad_s": self.gains.bandwidth,
            "open_loop_stop_rad": self.open_loop_stop,
            "elapsed_s": self.elapsed,
            "incomplete": self.incomplete,
        }
        for key, value in (
            ("local_position_max_rad", self.local_position_max),
            ("local_position_median_rad", self.local_position_median),
            ("local_velocity_max_rad_s", self.local_velocity_max),
            ("local_velocity_median_rad_s", self.local_velocity_median),
            ("feedback_rms_ratio", self.feedback_rms),
            ("feedback_peak_ratio", self.feedback_peak),
            ("tracking_position_error_rad", self.tracking_position_error),
            ("tracking_velocity_error_rad_s", self.tracking_velocity_error),
            ("open_loop_final_error_rad", self.open_loop_final_error),
            ("open_loop_divergence_time_s", self.open_loop_divergence_time),
        ):
            out[key] = num(value)
        for c in self.bounds:
            key = f"bound_{c.quantity}_{c.where}"
            out.update({f"{key}_excess": num(c.excess), f"{key}_relative": num(c.relative)})
            out.update({f"{key}_time_s": num(c.time), f"{key}_joint": c.joint})
        return out

    def __str__(self) -> str:
        verdict = "PASSED" if self.ok else "FAILED"
        if self.incomplete:
            verdict = f"INCOMPLETE, {self.incomplete}"
        lines = [
            f"Certificate: {self.robot}, {self.n_knots} knots, {self.interpolation}, "
            f"T = {self.duration:.4g} s: {verdict}",
            f"  {'check':<40}{'max':>10}{'median':>10}{'tol':>9}",
        ]
        for label, value, median, limit, note in self._rows(self.tolerances):
            med = f"{median:>10.2e}" if math.isfinite(median) else " " * 10
            mark = "ok  " if value <= limit else "FAIL"
            lines.append(f"  {label:<40}{value:>10.2e}{med}{limit:>9.1e}  {mark}  {note}".rstrip())
        if math.isfinite(self.open_loop_divergence_time):
            drift = (
                f"drifted {self.open_loop_stop:g} rad from the plan at "
                f"t = {self.open_loop_divergence_time:.3g} s"
            )
        else:
            drift = f"final position error {self.open_loop_final_error:.2e} rad"
        lines.append(f"  open loop (reported, not tested): {drift}")
        lines.append(
            f"  (PD tracking at {self.gains.bandwidth:g} rad/s, damping ratio "
            f"{self.gains.damping_ratio:g}; certified in {self.elapsed:.3f} s)"
        )
        return "\n".join(lines)

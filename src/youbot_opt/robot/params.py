"""Parameters of the planar youBot arm of study 1: the single source of truth.

Transcribes the tables of spec ``trajopt.md`` ("The arm", "Joint limits")
into immutable dataclasses: :class:`LinkParameters`, :class:`JointLimits`
(data-sheet units with SI properties), :class:`PlatformMounting` and
:class:`ArmParameters`, with :data:`YOUBOT_PLANAR`, the study's values, from
which the URDF, the Pinocchio model, the analytic oracle and the limits are
derived. The out-of-plane inertia completion: docs/design.md, "Module notes".

>>> YOUBOT_PLANAR.links[0].length  # [m]  # doctest: +SKIP
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field, replace

import numpy as np

from youbot_opt._checks import check_finite, check_nonnegative, check_positive
from youbot_opt._typing import Array
from youbot_opt.exceptions import ParameterError

__all__ = [
    "LinkParameters",
    "JointLimits",
    "PlatformMounting",
    "ArmParameters",
    "YOUBOT_PLANAR",
    "STUDY_Q_START",
    "STUDY_Q_GOAL",
]

STUDY_Q_START: tuple[float, float, float] = (-math.pi / 6, -math.pi / 6, -math.pi / 3)
"""Start configuration of study 1 in [rad]."""

STUDY_Q_GOAL: tuple[float, float, float] = (math.pi / 6, math.pi / 6, math.pi / 3)
"""Goal configuration of study 1 in [rad]."""


@dataclass(frozen=True, slots=True, kw_only=True)
class LinkParameters:
    """Geometry and inertia of one planar link.

    Attributes
    ----------
    length : float
        Distance from the link's joint to the next joint (or to the gripper
        tip for the last link) in [m].
    com_distance : float
        Distance from the link's joint to its centre of mass, along the link,
        in [m] (the study's ``theta``).
    mass : float
        Link mass in [kg].
    inertia : float
        Rotational inertia about the joint-axis direction at the centre of
        mass in [kg m^2].
    radius : float
        Radius of the cylinder used to draw the link in [m]; also sets the
        axial inertia of the 3-D completion (docs/design.md, "Module notes").
    """

    length: float
    com_distance: float
    mass: float
    inertia: float
    radius: float = 0.03

    def __post_init__(self) -> None:
        for name in ("length", "mass", "inertia", "radius"):
            object.__setattr__(self, name, check_positive(getattr(self, name), name))
        com = check_nonnegative(self.com_distance, "com_distance", unit="m")
        object.__setattr__(self, "com_distance", com)
        if 2.0 * self.inertia < self.axial_inertia:
            raise ParameterError(
                f"radius {self.radius} m gives an axial inertia {self.axial_inertia} kg m^2 "
                f"larger than 2 * inertia = {2.0 * self.inertia} kg m^2 (triangle inequality); "
                "use a smaller radius",
                name="radius",
                value=self.radius,
            )

    @property
    def axial_inertia(self) -> float:
        """Inertia about the link's own axis at the COM in [kg m^2] (``m r^2 / 2``)."""
        return 0.5 * self.mass * self.radius**2

    @property
    def inertia_tensor(self) -> Array:
        """Rotational inertia at the COM in the link frame in [kg m^2], shape (3, 3).

        The link frame has ``z`` along the link and ``y`` along the joint axis:
        ``diag(inertia, inertia, axial_inertia)``.
        """
        tensor = np.diag([self.inertia, self.inertia, self.axial_inertia])
        tensor.setflags(write=False)
        return tensor


@dataclass(frozen=True, slots=True, kw_only=True)
class JointLimits:
    """Data-sheet limits of one revolute joint, kept in data-sheet units.

    Attributes
    ----------
    lower_deg : float
        Lower position limit in [deg].
    upper_deg : float
        Upper position limit in [deg]; must exceed ``lower_deg``.
    speed_deg_s : float
        Symmetric speed limit ``|v| <= speed`` in [deg/s], > 0.
    torque_nm : float
        Symmetric torque limit ``|tau| <= torque`` in [N m], > 0.
    """

    lower_deg: float
    upper_deg: float
    speed_deg_s: float
    torque_nm: float

    def __post_init__(self) -> None:
        for name in ("lower_deg", "upper_deg"):
            object.__setattr__(self, name, check_finite(getattr(self, name), name, unit="deg"))
        for name in ("speed_deg_s", "torque_nm"):
            object.__setattr__(self, name, check_positive(getattr(self, name), name))
        if not self.lower_deg < self.upper_deg:
            raise ParameterError(
                f"upper_deg ({self.upper_deg}) must be greater than lower_deg ({self.lower_deg})",
                name="upper_deg",
                value=self.upper_deg,
            )

    @property
    def lower(self) -> float:
        """Lower position limit in [rad]."""
        return math.radians(self.lower_deg)

    @property
    def upper(self) -> float:
        """Upper position limit in [rad]."""
        return math.radians(self.upper_deg)

    @property
    def velocity(self) -> float:
        """Speed limit in [rad/s]."""
        return math.radians(self.speed_deg_s)

    @property
    def effort(self) -> float:
        """Torque limit in [N m]."""
        return self.torque_nm

    def scaled(self, s: float, *, position: bool = True) -> JointLimits:
        """Return the limits multiplied by ``s`` (the study's bound-scaling sweep).

        Parameters
        ----------
        s : float
            Scale factor in (0, 1]; 1.0 is the data sheet, 0.85 is 85 %.
        position : bool
            Also scale the position limits towards 0 (the study scaled "all
            bounds"); speed and torque limits are always scaled.

        Returns
        -------
        JointLimits
            A new instance.

        Raises
        ------
        ParameterError
            If ``s`` is not in (0, 1].
        """
        s = check_positive(s, "s")
        if s > 1.0:
            raise ParameterError(f"scale s must be in (0, 1], got {s}", name="s", value=s)
        p = s if position else 1.0
        return replace(
            self,
            lower_deg=p * self.lower_deg,
            upper_deg=p * self.upper_deg,
            speed_deg_s=s * self.speed_deg_s,
            torque_nm=s * self.torque_nm,
        )


@dataclass(frozen=True, slots=True, kw_only=True)
class PlatformMounting:
    """Position of joint 1 in the platform frame (x forward, z up).

    Attributes
    ----------
    a : float
        Horizontal offset of joint 1 along platform x in [m].
    h : float
        Height of joint 1 above the platform frame origin in [m].
    """

    a: float = 0.151 + 0.033
    h: float = 0.147

    def __post_init__(self) -> None:
        object.__setattr__(self, "a", check_finite(self.a, "a"))
        object.__setattr__(self, "h", check_finite(self.h, "h"))


def _read_only(values: list[float]) -> Array:
    arr = np.asarray(values, dtype=float)
    arr.setflags(write=False)
    return arr


@dataclass(frozen=True, slots=True, kw_only=True)
class ArmParameters:
    """The planar three-link youBot arm of study 1.

    Attributes
    ----------
    links : tuple of LinkParameters
        The three links, base to tip.
    limits : tuple of JointLimits
        Data-sheet limits of the three joints.
    mounting : PlatformMounting
        Position of joint 1 on the platform.
    gravity : float
        Gravitational acceleration in [m/s^2], acting along platform -z.
    damping : float
        Viscous joint damping ``b`` in [N m s/rad], the same on each joint
        (``tau_friction = -b v``). The study's paper has none (0); its MATLAB
        code used 0.1.
    name : str
        Robot name written into the URDF.
    """

    links: tuple[LinkParameters, ...]
    limits: tuple[JointLimits, ...]
    mounting: PlatformMounting = field(default_factory=PlatformMounting)
    gravity: float = 9.81
    damping: float = 0.0
    name: str = "youbot_arm_planar"

    def __post_init__(self) -> None:
        links = tuple(self.links)
        limits = tuple(self.limits)
        if len(links) != 3 or not all(isinstance(x, LinkParameters) for x in links):
            raise ParameterError(
                f"links must be 3 LinkParameters, got {self.links!r}", name="links", value=links
            )
        if len(limits) != 3 or not all(isinstance(x, JointLimits) for x in limits):
            raise ParameterError(
                f"limits must be 3 JointLimits, got {self.limits!r}", name="limits", value=limits
            )
        if not isinstance(self.mounting, PlatformMounting):
            raise ParameterError(
                f"mounting must be a PlatformMounting, got {self.mounting!r}",
                name="mounting",
                value=self.mounting,
            )
        object.__setattr__(self, "links", links)
        object.__setattr__(self, "limits", limits)
        gravity = check_nonnegative(self.gravity, "gravity", unit="m/s^2")
        object.__setattr__(self, "gravity", gravity)
        damping = check_nonnegative(self.damping, "damping", unit="N m s/rad")
        object.__setattr__(self, "damping", damping)
        if not isinstance(self.name, str) or not self.name.isidentifier():
            raise ParameterError(
                f"name must be an identifier-like string, got {self.name!r}",
                name="name",
                value=self.name,
            )

    @property
    def n_joints(self) -> int:
        """Number of joints (3)."""
        return len(self.links)

    @property
    def lengths(self) -> Array:
        """Link lengths in [m], shape (3,)."""
        return _read_only([x.length for x in self.links])

    @property
    def com_distances(self) -> Array:
        """Joint-to-COM distances in [m], shape (3,)."""
        return _read_only([x.com_distance for x in self.links])

    @property
    def masses(self) -> Array:
        """Link masses in [kg], shape (3,)."""
        return _read_only([x.mass for x in self.links])

    @property
    def inertias(self) -> Array:
        """Link inertias about the joint axis at the COM in [kg m^2], shape (3,)."""
        return _read_only([x.inertia for x in self.links])

    @property
    def q_lower(self) -> Array:
        """Lower position limits in [rad], shape (3,)."""
        return _read_only([x.lower for x in self.limits])

    @property
    def q_upper(self) -> Array:
        """Upper position limits in [rad], shape (3,)."""
        return _read_only([x.upper for x in self.limits])

    @property
    def velocity_limit(self) -> Array:
        """Speed limits in [rad/s], shape (3,)."""
        return _read_only([x.velocity for x in self.limits])

    @property
    def effort_limit(self) -> Array:
        """Torque limits in [N m], shape (3,)."""
        return _read_only([x.effort for x in self.limits])

    def scaled(self, s: float, *, position: bool = True) -> ArmParameters:
        """Return the arm with every joint limit scaled by ``s`` (see :meth:`JointLimits.scaled`).

        Parameters
        ----------
        s : float
            Scale factor in (0, 1].
        position : bool
            Also scale the position limits.

        Returns
        -------
        ArmParameters
            A new instance; links and mounting are unchanged.
        """
        return replace(self, limits=tuple(x.scaled(s, position=position) for x in self.limits))


YOUBOT_PLANAR = ArmParameters(
    links=(
        LinkParameters(length=0.155, com_distance=0.0775, mass=1.318, inertia=0.0031145),
        LinkParameters(length=0.135, com_distance=0.0675, mass=0.821, inertia=0.00172767),
        LinkParameters(length=0.2175, com_distance=0.10875, mass=0.769, inertia=0.0006764),
    ),
    limits=(
        JointLimits(lower_deg=-65.0, upper_deg=90.0, speed_deg_s=90.0, torque_nm=9.5),
        JointLimits(lower_deg=-151.0, upper_deg=146.0, speed_deg_s=90.0, torque_nm=6.0),
        JointLimits(lower_deg=-102.5, upper_deg=102.5, speed_deg_s=90.0, torque_nm=2.0),
    ),
    mounting=PlatformMounting(a=0.151 + 0.033, h=0.147),
    gravity=9.81,
    damping=0.0,
)
"""The study's arm: tables of spec ``trajopt.md``, no joint damping (the paper)."""

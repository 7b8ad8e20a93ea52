"""Rigid-body algorithms of Pinocchio transcribed into CasADi SX expressions.

Forward kinematics, frame placements, RNEA, CRBA and ABA in Pinocchio's local
formulation, rebuilt from the model's data because the PyPI ``pin`` wheel has
no ``pinocchio.casadi``; named, ``cse``-optimised Functions, exact and
differentiable to any order. Without ``model.damping``
(:func:`youbot_opt.dynamics.build_dynamics` adds it). References:
Featherstone, *Rigid Body Dynamics Algorithms* (2008), tables 5.1, 6.2, 7.1.

>>> symbolic = build_symbolic_model(model)  # doctest: +SKIP
"""

from __future__ import annotations

import re
from dataclasses import dataclass, field
from typing import TYPE_CHECKING

import casadi as ca
import numpy as np

from youbot_opt._typing import Array
from youbot_opt.dynamics import spatial_algebra
from youbot_opt.dynamics.tree import JointSpec, TreeSpec, as_pin_model, read_tree
from youbot_opt.exceptions import FrameNotFound

if TYPE_CHECKING:
    import pinocchio as pin

    from youbot_opt.robot.model import RobotModel

__all__ = ["SymbolicModel", "build_symbolic_model", "FUNCTION_OPTIONS"]

FUNCTION_OPTIONS: dict[str, bool] = {"cse": True}
"""Options for every Function built here (common-subexpression elimination)."""

#: An expression of this module: SX, or a DM constant not yet combined with one (the
#: Functions are built on ``SX`` symbols; CasADi's operators take the two together).
_Sym = ca.SX | ca.DM
_Placement = tuple[_Sym, _Sym]


def _subspace(joint: JointSpec) -> Array:
    """Motion subspace S (6,) of a 1-dof joint in its own frame (linear part first)."""
    s = np.zeros(6)
    if joint.kind == "revolute":
        s[3:] = joint.axis
    else:
        s[:3] = joint.axis
    return s


def _dot(s: Array, vec: _Sym) -> _Sym | float:
    """``sᵀ vec`` for a constant (6,) vector, skipping its zero entries."""
    out: _Sym | float = 0
    for k in range(6):
        if s[k] != 0.0:
            out = out + float(s[k]) * vec[k]
    return out


def _joint_placements(tree: TreeSpec, q: ca.SX) -> list[_Placement]:
    """Placement ``liMi(q)`` of each joint frame in its parent joint frame."""
    out: list[_Placement] = []
    for joint in tree.joints:
        qi = q[joint.index_v]
        rot0, pos0 = ca.DM(joint.rotation), ca.DM(joint.translation)
        if joint.kind == "revolute":
            out.append((ca.mtimes(rot0, spatial_algebra.rotation_about_axis(joint.axis, qi)), pos0))
        else:
            out.append((rot0, pos0 + ca.mtimes(rot0, ca.DM(joint.axis)) * qi))
    return out


def _world_placements(tree: TreeSpec, local: list[_Placement]) -> list[_Placement]:
    """Placement ``oMi(q)`` of each joint frame in the world frame."""
    world: list[_Placement] = []
    for i, joint in enumerate(tree.joints):
        if joint.parent == 0:
            world.append(local[i])
        else:
            world.append(spatial_algebra.compose(*world[joint.parent - 1], *local[i]))
    return world


def _rnea(tree: TreeSpec, q: ca.SX, v: ca.SX, a: ca.SX) -> ca.SX:
    """Joint torques ``M a + C v + g`` (plus armature ``a``) by recursive Newton-Euler.

    Gravity always enters, as in Pinocchio, through the fictitious root
    acceleration ``-gravity``; ``g(q)`` and ``C(q, v) v + g(q)`` are this
    function at ``v = a = 0`` and ``a = 0``.
    """
    local = _joint_placements(tree, q)
    n = len(tree.joints)
    root_acc = ca.DM(-tree.gravity)
    vel: list[_Sym] = []
    acc: list[_Sym] = []
    forces: list[_Sym] = []
    for i, joint in enumerate(tree.joints):
        s = ca.DM(_subspace(joint))
        vj = s * v[joint.index_v]
        if joint.parent == 0:
            vi = vj
            ai = spatial_algebra.act_inv_motion(*local[i], root_acc)
        else:
            vi = spatial_algebra.act_inv_motion(*local[i], vel[joint.parent - 1]) + vj
            ai = spatial_algebra.act_inv_motion(*local[i], acc[joint.parent - 1])
        ai = ai + s * a[joint.index_v] + spatial_algebra.cross_motion(vi, vj)
        inertia = ca.DM(joint.inertia)
        fi = ca.mtimes(inertia, ai) + spatial_algebra.cross_force(vi, ca.mtimes(inertia, vi))
        vel.append(vi)
        acc.append(ai)
        forces.append(fi)
    tau: list[_Sym | float] = [0] * tree.nv
    for i in range(n - 1, -1, -1):
        joint = tree.joints[i]
        tau[joint.index_v] = _dot(_subspace(joint), forces[i]) + joint.armature * a[joint.index_v]
        if joint.parent > 0:
            forces[joint.parent - 1] = forces[joint.parent - 1] + spatial_algebra.act_force(
                *local[i], forces[i]
            )
    return ca.vertcat(*tau)


def _crba(tree: TreeSpec, q: ca.SX) -> ca.SX:
    """Joint-space inertia matrix M(q) (armature on the diagonal) by the CRBA."""
    local = _joint_placements(tree, q)
    composite: list[_Sym] = [ca.DM(joint.inertia) for joint in tree.joints]
    for i in range(len(tree.joints) - 1, -1, -1):
        parent = tree.joints[i].parent
        if parent > 0:
            composite[parent - 1] = composite[parent - 1] + spatial_algebra.act_inertia(
                *local[i], composite[i]
            )
    mass = ca.SX.zeros(tree.nv, tree.nv)
    for i, joint in enumerate(tree.joints):
        s_i = _subspace(joint)
        force = ca.mtimes(composite[i], ca.DM(s_i))
        col = joint.index_v
        mass[col, col] = _dot(s_i, force) + joint.armature
        j = i
        while tree.joints[j].parent > 0:
            force = spatial_algebra.act_force(*local[j], force)
            j = tree.joints[j].parent - 1
            row = tree.joints[j].index_v
            mass[row, col] = _dot(_subspace(tree.joints[j]), force)
            mass[col, row] = mass[row, col]
    return mass


def _aba(tree: TreeSpec, q: ca.SX, v: ca.SX, tau: ca.SX) -> ca.SX:
    """Joint accelerations by Featherstone's articulated-body algorithm."""
    local = _joint_placements(tree, q)
    n = len(tree.joints)
    vel: list[_Sym] = []
    bias_acc: list[_Sym] = []
    art_inertia: list[_Sym] = []
    bias_force: list[_Sym] = []
    for i, joint in enumerate(tree.joints):
        vj = ca.DM(_subspace(joint)) * v[joint.index_v]
        if joint.parent == 0:
            vi = vj
        else:
            vi = spatial_algebra.act_inv_motion(*local[i], vel[joint.parent - 1]) + vj
        inertia = ca.DM(joint.inertia)
        vel.append(vi)
        bias_acc.append(spatial_algebra.cross_motion(vi, vj))
        art_inertia.append(inertia)
        bias_force.append(spatial_algebra.cross_force(vi, ca.mtimes(inertia, vi)))
    u_vec: dict[int, _Sym] = {}
    d_inv: dict[int, _Sym | float] = {}
    u_tau: dict[int, _Sym | float] = {}
    for i in range(n - 1, -1, -1):
        joint = tree.joints[i]
        s = ca.DM(_subspace(joint))
        u_vec[i] = ca.mtimes(art_inertia[i], s)
        d_inv[i] = 1 / (_dot(_subspace(joint), u_vec[i]) + joint.armature)
        u_tau[i] = tau[joint.index_v] - _dot(_subspace(joint), bias_force[i])
        if joint.parent > 0:
            reduced = art_inertia[i] - d_inv[i] * ca.mtimes(u_vec[i], u_vec[i].T)
            force = (
                bias_force[i] + ca.mtimes(reduced, bias_acc[i]) + u_vec[i] * (d_inv[i] * u_tau[i])
            )
            p = joint.parent - 1
            art_inertia[p] = art_inertia[p] + spatial_algebra.act_inertia(*local[i], reduced)
            bias_force[p] = bias_force[p] + spatial_algebra.act_force(*local[i], force)
    root_acc = ca.DM(-tree.gravity)
    acc: dict[int, _Sym] = {}
    qdd: list[_Sym | float] = [0] * tree.nv
    for i, joint in enumerate(tree.joints):
        parent_acc = root_acc if joint.parent == 0 else acc[joint.parent - 1]
        ai = spatial_algebra.act_inv_motion(*local[i], parent_acc) + bias_acc[i]
        qdd_i = d_inv[i] * (u_tau[i] - ca.dot(u_vec[i], ai))
        qdd[joint.index_v] = qdd_i
        acc[i] = ai + ca.DM(_subspace(joint)) * qdd_i
    return ca.vertcat(*qdd)


def _function(
    name: str, inputs: list[_Sym], outputs: list[_Sym], in_names: list[str], out_names: list[str]
) -> ca.Function:
    return ca.Function(name, inputs, outputs, in_names, out_names, FUNCTION_OPTIONS)


@dataclass(frozen=True, slots=True, kw_only=True)
class SymbolicModel:
    """Named CasADi Functions of a fixed-base robot, built from its ``pin.Model``.

    None of the dynamics Functions include ``model.damping``; armature is
    included exactly as Pinocchio does (``M + diag(armature)``).

    Attributes
    ----------
    nq, nv : int
        Numbers of configuration coordinates and of velocities (equal: a
        continuous joint's coordinate is its angle, not Pinocchio's (cos, sin)).
    damping : ndarray, shape (nv,)
        The model's viscous joint damping in [N m s/rad] (unused by these Functions).
    joint_names : tuple of str
        Names of the model's joints 1..njoints-1, in Pinocchio's order.
    frame_names : tuple of str
        Names of the model's operational frames.
    forward_kinematics : casadi.Function
        ``"forward_kinematics"``: q -> ``rotations`` (3, 3 n_joints), the joint
        frames' world rotations side by side (joint k in columns 3k..3k+2), and
        ``translations`` (3, n_joints) in [m] (joint k in column k).
    mass_matrix : casadi.Function
        ``"mass_matrix"`` (CRBA): q -> ``M`` (nv, nv) in [kg m^2].
    generalized_gravity : casadi.Function
        ``"generalized_gravity"``: q -> ``g`` (nv,) in [N m].
    nonlinear_effects : casadi.Function
        ``"nonlinear_effects"``: (q, v) -> ``nle = C(q, v) v + g(q)`` in [N m].
    rnea : casadi.Function
        ``"rnea"``: (q, v, a) -> ``tau = M a + C v + g`` in [N m].
    aba : casadi.Function
        ``"aba"`` (Featherstone's ABA): (q, v, tau) -> ``a`` in [rad/s^2].
    forward_dynamics_crba : casadi.Function
        ``"forward_dynamics_crba"``: (q, v, tau) -> ``a = M⁻¹ (tau - nle)`` by a
        symbolic linear solve of the CRBA matrix; same values as ``aba``.
    """

    nq: int
    nv: int
    damping: Array
    joint_names: tuple[str, ...]
    frame_names: tuple[str, ...]
    forward_kinematics: ca.Function
    mass_matrix: ca.Function
    generalized_gravity: ca.Function
    nonlinear_effects: ca.Function
    rnea: ca.Function
    aba: ca.Function
    forward_dynamics_crba: ca.Function
    _tree: TreeSpec = field(repr=False)

    def frame_placement(self, frame_name: str) -> ca.Function:
        """Return the Function q -> world placement ``(R, p)`` of an operational frame.

        Parameters
        ----------
        frame_name : str
            Name of a frame of the model (``pin.Model.frames``).

        Returns
        -------
        casadi.Function
            ``"frame_placement_<name>"`` (non-alphanumeric runs in the name
            replaced by ``_``): q (nq,) -> ``R`` (3, 3) and ``p`` (3,) in [m],
            equal to Pinocchio's ``data.oMf[frame_id]`` after ``updateFramePlacements``.

        Raises
        ------
        FrameNotFound
            If the model has no frame of that name; the message lists the frames.
        """
        frames = {frame.name: frame for frame in self._tree.frames}
        if frame_name not in frames:
            raise FrameNotFound(frame_name, self.frame_names)
        frame = frames[frame_name]
        q = ca.SX.sym("q", self.nq)
        rot0, pos0 = ca.DM(frame.rotation), ca.DM(frame.translation)
        rot: _Sym
        pos: _Sym
        if frame.parent_joint == 0:
            rot, pos = ca.SX(rot0), ca.SX(pos0)
        else:
            rotations, translations = self.forward_kinematics(q)
            k = frame.parent_joint - 1
            rot, pos = spatial_algebra.compose(
                rotations[:, 3 * k : 3 * k + 3], translations[:, k], rot0, pos0
            )
        suffix = re.sub(r"[^0-9A-Za-z]+", "_", frame_name).strip("_")
        name = f"frame_placement_{suffix}" if suffix else "frame_placement"
        return _function(name, [q], [rot, pos], ["q"], ["R", "p"])


def build_symbolic_model(model: RobotModel | pin.Model) -> SymbolicModel:
    """Transcribe a fixed-base Pinocchio model into named CasADi SX Functions.

    Parameters
    ----------
    model : pin.Model or RobotModel
        The robot; a ``RobotModel`` is unwrapped through its ``model`` attribute.
        All joints must be 1-dof revolute, continuous or prismatic (RX/RY/RZ,
        RevoluteUnaligned, RUBX/RUBY/RUBZ, RevoluteUnboundedUnaligned,
        PX/PY/PZ, PrismaticUnaligned); a continuous joint's entry of ``q`` is
        its angle in [rad] (:mod:`youbot_opt.dynamics.coordinates`).

    Returns
    -------
    SymbolicModel
        Forward kinematics, CRBA, gravity, nonlinear effects, RNEA, ABA and
        CRBA-based forward dynamics as CasADi Functions.

    Raises
    ------
    ModelError
        If a joint type is not supported (the message names it and lists the
        supported ones).
    ParameterError
        If ``model`` is not a ``pin.Model`` and holds none in ``.model``.
    """
    pin_model = as_pin_model(model)
    tree = read_tree(pin_model)
    nv = tree.nv
    q = ca.SX.sym("q", nv)
    v = ca.SX.sym("v", nv)
    a = ca.SX.sym("a", nv)
    tau = ca.SX.sym("tau", nv)
    zero = ca.SX.zeros(nv)
    world = _world_placements(tree, _joint_placements(tree, q))
    rotations = ca.horzcat(*[rot for rot, _ in world]) if world else ca.SX(3, 0)
    translations = ca.horzcat(*[pos for _, pos in world]) if world else ca.SX(3, 0)
    mass = _crba(tree, q)
    nle = _rnea(tree, q, v, zero)
    return SymbolicModel(
        nq=nv,
        nv=nv,
        damping=tree.damping,
        joint_names=tuple(joint.name for joint in tree.joints),
        frame_names=tuple(frame.name for frame in tree.frames),
        forward_kinematics=_function(
            "forward_kinematics",
            [q],
            [rotations, translations],
            ["q"],
            ["rotations", "translations"],
        ),
        mass_matrix=_function("mass_matrix", [q], [mass], ["q"], ["M"]),
        generalized_gravity=_function(
            "generalized_gravity", [q], [_rnea(tree, q, zero, zero)], ["q"], ["g"]
        ),
        nonlinear_effects=_function("nonlinear_effects", [q, v], [nle], ["q", "v"], ["nle"]),
        rnea=_function("rnea", [q, v, a], [_rnea(tree, q, v, a)], ["q", "v", "a"], ["tau"]),
        aba=_function("aba", [q, v, tau], [_aba(tree, q, v, tau)], ["q", "v", "tau"], ["a"]),
        forward_dynamics_crba=_function(
            "forward_dynamics_crba",
            [q, v, tau],
            [ca.solve(mass, tau - nle)],
            ["q", "v", "tau"],
            ["a"],
        ),
        _tree=tree,
    )

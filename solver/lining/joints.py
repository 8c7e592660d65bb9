"""Segmental linings (SPEC §1.6): the joints as contact rows, the segments' rigid modes, the joint results.

A joint is a cut through the lining normal to its mid-surface (radial on a circle) (:func:`solver.geometry.mesh.build_mesh` makes each face's
nodes twice). Over its contact strip, ``a`` high and centred on the mid-surface, the faces touch
node by node: a *normal row* per node pair, the jump ``J = (u_A - u_B)·e_θ`` (A the crown-side
face, B the invert side, e_θ the hoop direction towards increasing θ), so that the gap
``-J`` is the joint's opening, with unilateral contact; and a *tangential row*, the jump
``(u_A - u_B)·e_r``, bonded or with Coulomb friction. Outside the strip the faces are free (the
chamfers). The strip is integrated by the trapezoidal rule over its nodes (positive weights;
its resultant then lies between its first and last node, the strip's edges).

A joint on the symmetry line (at the crown or the invert) has one face in the half model; its
mirror image moves symmetrically, so the jump across it is twice the face's own hoop
displacement and the shear across it vanishes. Its rows are the normal ones alone, with the
jump ``-u·e_θ`` (crown) or ``u·e_θ`` (invert) of the one face: half the true jump, the
half model's share of the work ``∫ λ [u]``; the face is otherwise free (the symmetry line's
``u_x = 0`` no longer holds it).

The segments float: a segment cut by the symmetry line keeps its vertical translation, the
others translate both ways and rotate (:func:`rigid_modes`); only contact holds them
(:mod:`solver.contact.floating`).
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import scipy.linalg as la
import scipy.sparse as sp

from ..fe.assembly import Body
from ..fe.flexibility import interface_operator
from ..geometry.bodies import Joints, TunnelMesh


@dataclass(frozen=True)
class JointRows:
    """The contact rows of the joints, normal rows of each joint then its tangential rows.

    joint : (Rj,) joint of each row; normal : (Rj,) True for a normal row; across : (Rj,) m, the
    row's node's distance from the mid-surface along the cut (outward +); weight : (Rj,) m, the trapezoid weight of the node on its strip;
    B : (Rj, n) the jumps on the lining's free DOFs; on_axis : (J,) joints on the symmetry line.
    """

    joint: np.ndarray
    normal: np.ndarray
    across: np.ndarray
    weight: np.ndarray
    B: sp.csr_matrix
    on_axis: np.ndarray

    @property
    def size(self) -> int:
        return self.joint.size

    @property
    def partner(self) -> np.ndarray:
        """(Rj,) each tangential row's normal row (same joint, same node; a joint's normal rows
        come first, its tangential rows after them in the same order); -1 on normal rows."""
        per_joint = np.bincount(self.joint[self.normal], minlength=int(self.joint.max()) + 1)
        return np.where(self.normal, -1, np.arange(self.size) - per_joint[self.joint])


def hoop(theta_deg: float) -> tuple[np.ndarray, np.ndarray]:
    """Unit hoop (towards increasing θ) and outward radial directions at ``theta_deg`` (on
    another section: the turning angle of the outward normal, :attr:`Joints.normal`)."""
    t = np.radians(theta_deg)
    return np.array([np.cos(t), -np.sin(t)]), np.array([np.sin(t), np.cos(t)])


def strip_weights(across: np.ndarray, height: float) -> np.ndarray:
    """Trapezoid weights (m) of the face nodes at ``across`` (m from the mid-surface, increasing)
    over the strip of ``height`` centred on the mid-surface; zero outside it. A strip narrower
    than the node spacing is its one nearest node, weighted by the height."""
    inside = np.abs(across) <= 0.5 * height * (1 + 1e-9) + 1e-12
    w = np.zeros(across.size)
    idx = np.flatnonzero(inside)
    if idx.size < 2:
        w[np.argmin(np.abs(across))] = height
        return w
    r = across[idx]
    h = np.diff(r)
    w[idx[:-1]] += 0.5 * h
    w[idx[1:]] += 0.5 * h
    return w


def joint_rows(lining: Body, joints: Joints, *, height: float, shear: bool) -> JointRows:
    """The joints' contact rows (normal, and tangential ones when ``shear``: every interface model of
    the joints but a frictionless one has them)."""
    rows_joint, rows_normal, rows_across, rows_weight = [], [], [], []
    nodes_a, nodes_b, dirs = [], [], []
    for j in range(joints.size):
        before, after = joints.before[j], joints.after[j]
        across = joints.across[j]
        w = strip_weights(across, height)
        keep = np.flatnonzero(w > 0)
        e_t, e_r = hoop(joints.normal[j])
        on_axis = before.size == 0 or after.size == 0
        kinds = [(True, e_t)] + ([] if on_axis or not shear else [(False, e_r)])
        for is_normal, e in kinds:
            for k in keep:
                rows_joint.append(j)
                rows_normal.append(is_normal)
                rows_across.append(across[k])
                rows_weight.append(w[k])
                nodes_a.append(before[k] if before.size else -1)
                nodes_b.append(after[k] if after.size else -1)
                dirs.append(e)
    dirs = np.array(dirs).T
    na, nb = np.array(nodes_a), np.array(nodes_b)
    R = na.size
    B = sp.csr_matrix((R, lining.n))
    for nodes, sign in ((na, 1.0), (nb, -1.0)):
        has = np.flatnonzero(nodes >= 0)
        if has.size:
            part = interface_operator(lining, nodes[has], dirs[:, has], sign)
            place = sp.csr_matrix((np.ones(has.size), (has, np.arange(has.size))), shape=(R, has.size))
            B = B + place @ part
    axis = np.array([joints.before[j].size == 0 or joints.after[j].size == 0 for j in range(joints.size)])
    return JointRows(joint=np.array(rows_joint), normal=np.array(rows_normal, bool), across=np.array(rows_across),
                     weight=np.array(rows_weight), B=sp.csr_matrix(B), on_axis=axis)


def axis_faces(joints: Joints) -> np.ndarray:
    """Lining nodes of the joints' faces on the symmetry line (not held by it: in contact instead)."""
    faces = [f for j in range(joints.size) if joints.on_axis(j) for f in (joints.before[j], joints.after[j])]
    return np.concatenate(faces) if faces else np.zeros(0, np.int64)


@dataclass(frozen=True)
class RigidModes:
    """The lining's rigid modes on its free DOFs, ``vectors`` (n, k), with per mode its
    ``segment`` and a ``label``; ``pins`` (k,) free DOFs whose values fix every mode (the
    generalized inverse holds them at zero)."""

    vectors: np.ndarray
    segment: np.ndarray
    label: tuple[str, ...]
    pins: np.ndarray


def rigid_modes(lining: Body, mesh: TunnelMesh, avoid: np.ndarray) -> RigidModes:
    """Every rigid motion of each segment that the lining's supports (the symmetry line)
    leave free: the null space of the segment's translations and rotation about the tunnel
    axis at the held DOFs. ``avoid``: free DOFs not to pin (those the contact rows act on)."""
    joints = mesh.joints
    p = mesh.lining.p
    c = np.asarray(mesh.center, float)[:, None]
    scale = float(np.max(np.hypot(*(p - c))))
    dof = lining.dof_of_node  # (2, N) full DOFs
    held = np.ones(lining.basis.N, bool)
    held[lining.free] = False
    vectors, segment, label = [], [], []
    for s in range(joints.segments):
        on = joints.segment == s
        cand = np.zeros((3, lining.basis.N))
        cand[0, dof[0, on]] = 1.0
        cand[1, dof[1, on]] = 1.0
        rel = (p[:, on] - c) / scale
        cand[2, dof[0, on]], cand[2, dof[1, on]] = rel[1], -rel[0]  # clockwise, towards increasing θ
        at_held = cand[:, held].T
        null = la.null_space(at_held) if np.any(at_held) else np.eye(3)
        theta = np.degrees(np.arctan2(p[0, on] - c[0, 0], p[1, on] - c[1, 0]))
        where = f"segment {s} ({theta.min():.0f}-{theta.max():.0f} deg)"
        names = ("horizontal translation", "vertical translation", "rotation about the tunnel axis")
        for k in range(null.shape[1]):
            full = null[:, k] @ cand
            u = full[lining.free]
            vectors.append(u if lining.skew is None else lining.skew.apply_transpose(u))
            segment.append(s)
            main = int(np.argmax(np.abs(null[:, k])))
            label.append(f"{where}: {names[main] if null.shape[1] < 3 else 'rigid motion ' + str(k)}")
    V = np.column_stack(vectors)
    allowed = np.ones(lining.n, bool)
    allowed[avoid] = False
    cand_dofs = np.flatnonzero(allowed & np.any(V != 0.0, axis=1))
    _, _, piv = la.qr(V[cand_dofs].T, mode="economic", pivoting=True)
    pins = np.sort(cand_dofs[piv[:V.shape[1]]])
    if np.linalg.matrix_rank(V[pins]) < V.shape[1]:
        raise RuntimeError("no set of lining DOFs fixes every segment's rigid modes")
    return RigidModes(vectors=V, segment=np.array(segment), label=tuple(label), pins=pins)


def joint_kkt(rows: JointRows, t: np.ndarray, jump: np.ndarray, law, *, p_ref: float, u_ref: float) -> float:
    """The KKT measure of :func:`solver.contact.kkt.kkt_residual` on the joints' rows: unilateral
    contact on the normal rows, and on the tangential ones the bond (J = 0) or the Coulomb
    law's natural map (``law``: the case's ``lining.joints``)."""
    n, s = rows.normal, ~rows.normal
    lam, gap = t[n], -jump[n]
    parts = [max(0.0, -float(lam.min(initial=0.0))) / p_ref, max(0.0, -float(gap.min(initial=0.0))) / u_ref,
             float(np.max(np.abs(lam * gap), initial=0.0)) / (p_ref * u_ref)]
    if s.any():
        if law.shear == "bonded":
            parts.append(float(np.max(np.abs(jump[s]))) / u_ref)
        else:
            bound = law.friction * np.maximum(t[rows.partner[s]], 0.0)
            nat = t[s] - np.clip(t[s] + (p_ref / u_ref) * jump[s], -bound, bound)
            parts.append(float(np.max(np.abs(nat))) / p_ref)
    return max(parts)


@dataclass(frozen=True)
class JointResults:
    """Per joint, crown to invert (SPEC §3): theta (deg), thrust (N/m, compression +), moment
    (N·m/m, + when the intrados is compressed, the section's convention), opening (m, the
    largest gap over the strip), rotation (rad, the faces' relative rotation, + opening at the
    extrados), open (bool), and the strip height (m) the joints were solved with."""

    theta: np.ndarray
    thrust: np.ndarray
    moment: np.ndarray
    opening: np.ndarray
    rotation: np.ndarray
    open: np.ndarray
    contact_height: float

    @property
    def eccentricity_ratio(self) -> np.ndarray:
        """|M| / (N a/2): where in its half-height the thrust acts (≤ 1: inside the strip)."""
        return np.abs(self.moment) / np.maximum(self.thrust * 0.5 * self.contact_height, 1e-300)


def joint_results(mesh: TunnelMesh, rows: JointRows, t: np.ndarray, jump: np.ndarray, u_lining: np.ndarray, *,
                  height: float, gap_tol: float) -> JointResults:
    """The joints' forces from their contact tractions ``t`` and jumps ``jump`` (at ``rows``),
    their opening and their faces' rotation from the lining's nodal displacement ``u_lining`` (2, N)."""
    joints = mesh.joints
    n = joints.size
    thrust, moment, opening, rotation = (np.zeros(n) for _ in range(4))
    is_open = np.zeros(n, bool)
    for j in range(n):
        normal = (rows.joint == j) & rows.normal
        lam, w, r = t[normal], rows.weight[normal], rows.across[normal]
        thrust[j] = float(np.sum(w * lam))
        moment[j] = -float(np.sum(w * lam * r))
        factor = 2.0 if rows.on_axis[j] else 1.0
        gap = -jump[normal] * factor
        opening[j] = max(0.0, float(gap.max()))
        is_open[j] = bool(gap.max() > gap_tol)
        e_t, _ = hoop(joints.normal[j])
        before, after = joints.before[j], joints.after[j]
        ua = e_t @ u_lining[:, before] if before.size else -(e_t @ u_lining[:, after])
        ub = e_t @ u_lining[:, after] if after.size else -(e_t @ u_lining[:, before])
        rotation[j] = float(np.polyfit(joints.across[j], ub - ua, 1)[0])
    return JointResults(theta=joints.theta.copy(), thrust=thrust, moment=moment, opening=opening,
                        rotation=rotation, open=is_open, contact_height=height)

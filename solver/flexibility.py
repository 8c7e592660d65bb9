"""From the two elastic bodies to the interface form of the contact problem.

``condense_interface`` factorizes each body once (interface DOFs last, see
:mod:`solver.linalg`) and returns the dense interface flexibility
``S = B K^+ B^T`` and ``d = B K^+ f`` of :class:`solver.contact.DualProblem`;
``recover_displacements`` turns a contact pressure back into displacements
with one more solve per body.
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import scipy.sparse as sp

from .assembly import BodySystem, System
from .contact import DualProblem
from .linalg import InterfaceFactor
from .mesh import Interface


@dataclass
class BodyInterface:
    """One body's factorization and its interface operator.

    ``B`` (m, n) maps free DOFs to ``sign * ν·u`` at the interface nodes
    (sign +1 ground, -1 lining), so ``[u]ν = B' u' + B'' u''``.
    """

    system: BodySystem
    B: sp.csr_matrix
    factor: InterfaceFactor
    dofs: np.ndarray  # interface free DOFs, the factor's trailing block
    Bd: np.ndarray    # (m, k) dense B restricted to ``dofs``
    fixed_dof: int | None = None  # generalized-inverse pin (lining only)

    def solve(self, rhs: np.ndarray) -> np.ndarray:
        """``K^+ rhs`` on the free DOFs (the pinned DOF, if any, is zero)."""
        if self.fixed_dof is None:
            return self.factor.solve(rhs)
        keep = np.arange(rhs.size) != self.fixed_dof
        x = np.zeros_like(rhs)
        x[keep] = self.factor.solve(rhs[keep])
        return x


def interface_operator(body: BodySystem, nodes: np.ndarray, normal: np.ndarray, sign: float) -> sp.csr_matrix:
    """Sparse ``sign * ν·u`` at ``nodes`` on the body's free DOFs, shape (m, n)."""
    rows, cols, vals = [], [], []
    for c in range(2):
        dof = body.free_of[c, nodes]
        ok = dof >= 0
        rows.append(np.flatnonzero(ok))
        cols.append(dof[ok])
        vals.append(sign * normal[c, ok])
    m = nodes.size
    return sp.csr_matrix((np.concatenate(vals), (np.concatenate(rows), np.concatenate(cols))), shape=(m, body.n))


def _factor_body(body: BodySystem, B: sp.csr_matrix, pin: int | None) -> BodyInterface:
    dofs = np.unique(B.indices)
    K, groups = body.K, body.node_of_dof()
    if pin is not None:
        keep = np.flatnonzero(np.arange(body.n) != pin)
        factor = InterfaceFactor(K[keep][:, keep], dofs - (dofs > pin), groups[keep])
    else:
        factor = InterfaceFactor(K, dofs, groups)
    return BodyInterface(system=body, B=B, factor=factor, dofs=dofs,
                         Bd=B[:, dofs].toarray(), fixed_dof=pin)


def _lining_pin(body: BodySystem, interface_nodes: np.ndarray) -> int:
    """A lining y-DOF away from the interface: pins the zero mode for K''^+."""
    ys = body.free_of[1].copy()
    ys[interface_nodes] = -1
    candidates = ys[ys >= 0]
    return int(candidates[candidates.size // 2])


def condense_interface(system: System, iface: Interface, g0: float):
    """Factor both bodies and build the :class:`DualProblem` (plus the body data)."""
    ground = system.ground
    lining = system.lining
    Bg = interface_operator(ground, iface.ground_node, iface.normal, +1.0)
    Bl = interface_operator(lining, iface.lining_node, iface.normal, -1.0)
    g = _factor_body(ground, Bg, None)
    l = _factor_body(lining, Bl, _lining_pin(lining, iface.lining_node))
    S = np.zeros((iface.size, iface.size))
    d = np.zeros(iface.size)
    for body in (g, l):
        S += body.factor.flexibility(body.Bd)
        d += body.B @ body.solve(body.system.f)
    F2 = float(lining.rigid_vertical() @ lining.f)
    dual = DualProblem(S=0.5 * (S + S.T), d=d, g0=np.full(iface.size, g0), w=iface.weight,
                       nu2=iface.normal[1].copy(), F2=F2)
    return dual, g, l


def recover_displacements(g: BodyInterface, l: BodyInterface, lam: np.ndarray, a: float,
                          w: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Free-DOF displacements of ground and lining for pressure ``lam`` and translation ``a``."""
    force = w * lam
    u_g = g.solve(g.system.f - g.B.T @ force)
    u_l = l.solve(l.system.f - l.B.T @ force) + a * l.system.rigid_vertical()
    return u_g, u_l

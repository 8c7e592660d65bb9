"""From the two elastic bodies to the interface form of the contact problem.

Interface unknowns are the tractions ``t = [λ; s]``: the normal pressure λ at the m
interface nodes and the shear s at the m - 2 nodes off the symmetry line (at the
crown and the invert the tangential direction is the symmetry line's normal, which
both bodies hold, so s = 0 there by symmetry). The force on the lining at node i is
``w_i (λ_i ν_i + s_i τ_i)`` and its opposite acts on the ground.

``B`` maps a body's free DOFs to ``sign · [ν·u; τ·u]`` at the interface rows (sign +1
ground, -1 lining), so the jumps ``J = [[u]ν; [u]τ] = B' u' + B'' u''``. Each body is
factorized once with its interface DOFs ordered last (:mod:`solver.linalg`); the
dense flexibility ``S = B K⁺ Bᵀ`` then costs one triangular solve, and for loads
``f`` the jumps are ``J = d - S W t - a r`` with ``d = B K⁺ f`` and ``r = [ν2; τ2]``
the jumps of a unit rigid upward translation ``a`` of the lining.
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import scipy.sparse as sp

from .assembly import Body
from .linalg import InterfaceFactor
from .mesh import Interface


def interface_rows(iface: Interface) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Node and direction (2, R) of every interface row: m normal rows, then m - 2 tangential."""
    m = iface.size
    tangential = np.arange(1, m - 1)
    nodes = np.r_[np.arange(m), tangential]
    directions = np.hstack([iface.normal, iface.tangent[:, tangential]])
    return nodes, directions, tangential


def interface_operator(body: Body, nodes: np.ndarray, directions: np.ndarray, sign: float) -> sp.csr_matrix:
    """Sparse ``sign · direction·u`` at ``nodes`` on the body's free DOFs, shape (R, n)."""
    rows, cols, vals = [], [], []
    for c in range(2):
        dof = body.free_of[c, nodes]
        ok = (dof >= 0) & (directions[c] != 0.0)
        rows.append(np.flatnonzero(ok))
        cols.append(dof[ok])
        vals.append(sign * directions[c, ok])
    return sp.csr_matrix((np.concatenate(vals), (np.concatenate(rows), np.concatenate(cols))),
                         shape=(nodes.size, body.n))


@dataclass
class FactoredBody:
    """A body's factorization and its interface operator ``B`` (R, n)."""

    body: Body
    B: sp.csr_matrix
    factor: InterfaceFactor
    pin: int | None = None  # generalized-inverse pin (lining only)

    def solve(self, rhs: np.ndarray) -> np.ndarray:
        """``K⁺ rhs`` on the free DOFs (the pinned DOF, if any, is zero)."""
        if self.pin is None:
            return self.factor.solve(rhs)
        keep = np.arange(rhs.shape[0]) != self.pin
        x = np.zeros_like(rhs)
        x[keep] = self.factor.solve(rhs[keep])
        return x

    def flexibility(self, rows: np.ndarray | slice = slice(None)) -> np.ndarray:
        """Dense ``B K⁺ Bᵀ`` restricted to ``rows`` by one triangular solve on the trailing factor block."""
        dofs = np.unique(self.B.indices)  # the factor's trailing block, in this order
        return self.factor.flexibility(self.B[rows][:, dofs].toarray())


def factor_body(body: Body, B: sp.csr_matrix, pin: int | None = None) -> FactoredBody:
    """Factorize ``body.K`` with the DOFs ``B`` touches ordered last (minus ``pin``)."""
    dofs = np.unique(B.indices)
    K, groups = body.K, body.node_of_dof()
    if pin is not None:
        keep = np.flatnonzero(np.arange(body.n) != pin)
        factor = InterfaceFactor(K[keep][:, keep], dofs - (dofs > pin), groups[keep])
    else:
        factor = InterfaceFactor(K, dofs, groups)
    return FactoredBody(body=body, B=B, factor=factor, pin=pin)


def lining_pin(body: Body, interface_nodes: np.ndarray) -> int:
    """A lining y-DOF away from the interface: pins the zero mode for K''⁺."""
    ys = body.free_of[1].copy()
    ys[interface_nodes] = -1
    candidates = ys[ys >= 0]
    return int(candidates[candidates.size // 2])

"""From the two elastic bodies to the interface form of the contact problem.

Interface unknowns are the tractions ``t = [λ; s]``: the normal pressure λ at the m
interface nodes and the shear s at the m - 2 nodes off the symmetry line (at the
crown and the invert the tangential direction is the symmetry line's normal, which
both bodies hold, so s = 0 there by symmetry). The force on the lining at node i is
``w_i (λ_i ν_i + s_i τ_i)`` and its opposite acts on the ground.

``B`` maps a body's free DOFs to ``sign · [ν·u; τ·u]`` at the interface rows (sign +1
ground, -1 lining), so the jumps ``J = [[u]ν; [u]τ] = B' u' + B'' u''``. The interface
nodes of both bodies carry their normal and tangential components as unknowns (a skew
basis, :func:`solver.fe.assembly.assemble_body`), so each row of ``B`` acts on one unknown
(at the crown and the invert, where x is held, the normal is vertical and the row is
``±u_y`` itself). Each body is
factorized once with the interface unknowns its contact model needs ordered last
(:class:`FactoredBody`, :mod:`solver.fe.linalg`); the dense flexibility ``S = B K⁺ Bᵀ``
then comes from the factor's trailing block, and for loads
``f`` the jumps are ``J = d - S W t - a r`` with ``d = B K⁺ f`` and ``r = [ν2; τ2]``
the jumps of a unit rigid upward translation ``a`` of the lining.
"""
from __future__ import annotations

from typing import Literal

import numpy as np
import scipy.sparse as sp

from .assembly import Body
from .linalg import InterfaceFactor, nested_dissection
from ..geometry.bodies import Interface


def interface_rows(iface: Interface) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Node and direction (2, R) of every interface row: m normal rows, then m - 2 tangential."""
    m = iface.size
    tangential = np.arange(1, m - 1)
    nodes = np.r_[np.arange(m), tangential]
    directions = np.hstack([iface.normal, iface.tangent[:, tangential]])
    return nodes, directions, tangential


def interface_operator(body: Body, nodes: np.ndarray, directions: np.ndarray, sign: float) -> sp.csr_matrix:
    """Sparse ``sign · direction·u`` at ``nodes`` on the body's free DOFs (in its basis: ``B T``
    for a skew body), shape (R, n). Along a skew node's own normal or tangent a row has one
    entry: the other's is ``±(ν_x ν_y - ν_y ν_x)``, exactly zero, and dropped."""
    rows, cols, vals = [], [], []
    for c in range(2):
        dof = body.free_of[c, nodes]
        ok = (dof >= 0) & (directions[c] != 0.0)
        rows.append(np.flatnonzero(ok))
        cols.append(dof[ok])
        vals.append(sign * directions[c, ok])
    B = sp.csr_matrix((np.concatenate(vals), (np.concatenate(rows), np.concatenate(cols))),
                      shape=(nodes.size, body.n))
    if body.skew is not None:
        B = sp.csr_matrix(B @ body.skew.matrix())
        B.eliminate_zeros()
    return B


#: Which interface rows a factorization serves with its trailing block: ``"normal"``
#: (frictionless contact needs only ``S_νν``) or ``"all"`` (Coulomb, bonded).
Rows = Literal["normal", "all"]


def rows_of_model(interface_model: str) -> Rows:
    """The rows an interface model's contact problem needs."""
    return "normal" if interface_model == "frictionless" else "all"


class FactoredBody:
    """A body, its interface operator ``B`` (R, n) and its factorizations, built on first use.

    Two factorizations can serve the interface. ``"all"`` orders the normal and the
    tangential unknowns of every interface node last, ``"normal"`` only the normal ones
    (the body's skew basis makes them unknowns of their own): half the trailing block,
    an eighth of its dense factorization. A result is always computed with the
    factorization its interface model needs, so it never depends on which the model
    built before.

    Parameters
    ----------
    body : the assembled body.
    B : its interface rows: m normal rows first, then tangential ones.
    m : number of rows the ``"normal"`` factorization serves (the interface's normal rows,
        and a segmental lining's joint rows after them).
    pin : generalized-inverse pins (lining only): DOFs held at zero, one per rigid mode
        (an int, or an array for a segmental lining's several modes).
    """

    def __init__(self, body: Body, B: sp.csr_matrix, m: int, pin: int | np.ndarray | None = None):
        self.body, self.B, self.m = body, B, m
        #: per ``Rows``: the factorization and ``B``'s rows it serves, on its ``last`` unknowns
        self._factors: dict[str, tuple[InterfaceFactor, sp.csr_matrix]] = {}
        self._order = None
        n = body.n
        self._keep = None
        if pin is not None:
            keep = np.ones(n, bool)
            keep[np.atleast_1d(pin)] = False
            self._keep = np.flatnonzero(keep)

    def _restrict(self, A: sp.spmatrix) -> sp.spmatrix:
        return A if self._keep is None else A[self._keep][:, self._keep]

    def _columns(self, B: sp.csr_matrix) -> sp.csr_matrix:
        return B if self._keep is None else B[:, self._keep].tocsr()

    #: the stiffness over the one factorized (:class:`ScaledBody` has its own)
    scale = 1.0

    @property
    def pinned(self) -> bool:
        """Whether a DOF is pinned (a floating body): then ``K K⁺ f`` differs from ``f`` there."""
        return self._keep is not None

    @property
    def base(self) -> "FactoredBody":
        """The body whose factorizations serve (itself; a :class:`ScaledBody`'s base)."""
        return self

    def stiffness(self) -> sp.csr_matrix:
        """The body's stiffness on its free DOFs (:class:`ScaledBody` scales it)."""
        return self.body.K

    def drop(self) -> None:
        """Forget the factorizations (rebuilt on next use)."""
        self._factors.clear()

    def matrix(self) -> tuple[sp.spmatrix, np.ndarray]:
        """The matrix every factorization of this body is of (``K`` without the pinned DOF)
        and its fill-reducing ordering (:meth:`order`)."""
        return self._restrict(self.body.K), self.order()

    def order(self) -> np.ndarray:
        """The fill-reducing ordering of :meth:`matrix`'s unknowns (found once: the yielding zone's
        factorizations reorder it, :mod:`solver.stages.region`)."""
        if self._order is None:
            nodes = self.body.node_of_dof()
            self._order = nested_dissection(self.body.basis.mesh, nodes if self._keep is None else nodes[self._keep])
        return self._order

    def factor(self, rows: Rows) -> tuple[InterfaceFactor, sp.csr_matrix]:
        """The factorization serving ``rows`` and those rows of ``B`` in its unknowns, as
        columns of its ``last`` unknowns (built on first use)."""
        if rows not in self._factors:
            K, order = self.matrix()
            B = self._columns(self.B[: self.m] if rows == "normal" else self.B)
            factor = InterfaceFactor(K, in_row_order(B), order)
            on_last = B[:, factor.last].tocsr()
            if on_last.nnz != B.nnz:
                raise AssertionError("interface rows reach beyond the trailing block")
            self._factors[rows] = (factor, on_last)
        return self._factors[rows]

    def flexibility(self, rows: Rows) -> np.ndarray:
        """Dense ``B K⁺ Bᵀ`` of the normal rows or of all rows, from the trailing factor
        block (:meth:`InterfaceFactor.flexibility`)."""
        factor, on_last = self.factor(rows)
        return factor.flexibility(on_last)

    # A load case in two halves around the contact solve: ``forward`` its load, read the
    # interface jumps ``B K⁺ f`` it gives, solve the contact problem, then ``backward`` with
    # the interface tractions: one forward and one backward triangular solve in all.
    def forward(self, f: np.ndarray, rows: Rows) -> np.ndarray:
        """The first half of ``K⁺ f`` (``f`` on the free DOFs), for :meth:`jumps` and
        :meth:`backward`."""
        factor, _ = self.factor(rows)
        return factor.forward(f if self._keep is None else f[self._keep])

    def jumps(self, y: np.ndarray, rows: Rows) -> np.ndarray:
        """``B K⁺ f`` at the rows the factorization serves (the m normal rows for
        ``"normal"``, all rows for ``"all"``), from ``y = forward(f)``."""
        factor, on_last = self.factor(rows)
        return on_last @ factor.interface(y)

    def backward(self, y: np.ndarray, rows: Rows, Wt: np.ndarray | None = None) -> np.ndarray:
        """``K⁺ (f - Bᵀ Wt)`` on the free DOFs (the pinned DOF, if any, is zero) from
        ``y = forward(f)``; ``Wt`` (R,) weighted interface tractions, zero on the rows the
        factorization does not serve. For an (n, j) ``y``, ``Wt`` is (R, j) and the j
        columns are solved in one sweep over the factor."""
        factor, on_last = self.factor(rows)
        if Wt is not None:
            y = y - factor.lift(on_last.T @ Wt[: on_last.shape[0]])
        x = factor.backward(y)
        if self._keep is None:
            return x
        u = np.zeros((self.body.n,) + x.shape[1:])
        u[self._keep] = x
        return u


class ScaledBody:
    """A :class:`FactoredBody` whose stiffness is ``scale`` times the one it factorized (the
    same body with every Young's modulus multiplied by ``scale``): ``K⁺`` and the flexibility
    divide by it, the loads' forward half is unchanged. What a sweep over the ground's
    stiffness shares one factorization by."""

    def __init__(self, base: "FactoredBody", scale: float):
        self.base, self.scale = base, float(scale)

    def __getattr__(self, name):  # body, B, m, forward, factor, ... as the base's
        return getattr(self.base, name)

    def jumps(self, y: np.ndarray, rows: Rows) -> np.ndarray:
        return self.base.jumps(y, rows) / self.scale

    def backward(self, y: np.ndarray, rows: Rows, Wt: np.ndarray | None = None) -> np.ndarray:
        return self.base.backward(y, rows, Wt) / self.scale

    def flexibility(self, rows: Rows) -> np.ndarray:
        return self.base.flexibility(rows) / self.scale

    def stiffness(self) -> sp.csr_matrix:
        return self.scale * self.base.body.K


def in_row_order(B: sp.csr_matrix) -> np.ndarray:
    """The unknowns ``B`` acts on, in the order its rows first reach them: ordered last in
    that order, one-unknown rows find the flexibility in the trailing block's order."""
    first = np.unique(B.indices, return_index=True)[1]
    return B.indices[np.sort(first)].astype(np.int64)


def lining_pin(body: Body, interface_nodes: np.ndarray) -> int:
    """A lining y-DOF away from the interface: pins the zero mode for K''⁺."""
    ys = body.free_of[1].copy()
    ys[interface_nodes] = -1
    candidates = ys[ys >= 0]
    return int(candidates[candidates.size // 2])

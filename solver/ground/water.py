"""Groundwater (SPEC §1.4) as plain functions: hydrostatic pore pressure, water pressure on a
curved boundary, steady seepage towards a drained lining and its inflow.

The ground is analysed in effective stress. Stage 0 has hydrostatic pore pressure
``u0 = γw max(z - z_table, 0)``; K0 acts on the effective stress.

- The excavation releases the *effective* traction σ′0·n (:func:`effective_release`): the
  water stays in the ground, and in the gap and against the lining, at ``u0``.
- ``watertight``: the pore pressure stays hydrostatic; ``u0`` acts on the lining's extrados
  (:func:`pressure_load`), whose resultant is Archimedes' buoyancy of the lining.
- ``drained``: the excavation boundary is at zero pore pressure and the ground reaches steady
  seepage (:func:`seepage`); the change of pore pressure ``Δp = p - u0`` loads the skeleton
  with the seepage force ``-∫ ∇Δp · v`` (:func:`seepage_load`), and no water acts on the lining.

Boundary integrals are exact on the isoparametric (quadratic) edges: each edge is split where
the water table crosses it and integrated by Gauss-Legendre on each piece (pressure linear in
depth, geometry quadratic: degree 5 per piece).
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ..fe.linalg import Cholesky, _SYS_L, _SYS_LT, nested_dissection

_GAUSS = np.polynomial.legendre.leggauss(4)


def hydrostatic(y: np.ndarray, table: float | None, unit_weight: float) -> np.ndarray:
    """Hydrostatic pore pressure u0 (Pa, compression positive) at heights ``y`` (m, up positive)."""
    y = np.asarray(y, dtype=float)
    if table is None:
        return np.zeros_like(y)
    return unit_weight * np.maximum(-y - table, 0.0)


def _edges(ring: np.ndarray) -> np.ndarray:
    """(3, K) node triples (vertex, edge node, vertex) of the quadratic edges of a ring of nodes
    ordered crown to invert, alternating vertex / edge node."""
    return np.stack([ring[0:-1:2], ring[1::2], ring[2::2]])


def boundary_load(p: np.ndarray, dof_of_node: np.ndarray, n_dofs: int, ring: np.ndarray, center,
                  traction, table: float | None) -> np.ndarray:
    """Full-DOF nodal load ``∫ N_i t ds`` of a traction on the quadratic edges of ``ring``.

    ``traction(x, n)`` gives the traction (2, ...) at points ``x`` (2, ...) where ``n`` (2, ...)
    is the unit normal pointing away from the tunnel axis ``center``. Each edge is split where
    it crosses the water ``table`` (depth, m) so that a pressure with a kink there is
    integrated exactly.
    """
    tri = _edges(ring)
    X = p[:, tri]  # (2, 3, K)
    # x(s) = X0 N0 + Xm Nm + X1 N1 on s in [0, 1]: x(s) = A s² + B s + X0
    A = 2.0 * X[:, 0] - 4.0 * X[:, 1] + 2.0 * X[:, 2]
    B = -3.0 * X[:, 0] + 4.0 * X[:, 1] - X[:, 2]
    K = tri.shape[1]
    cuts = np.full((K, 2), np.nan)
    if table is not None:
        a, b, c = A[1], B[1], X[1, 0] + table  # y(s) = -table
        disc = b * b - 4.0 * a * c
        ok = disc >= 0
        with np.errstate(divide="ignore", invalid="ignore"):
            sq = np.sqrt(np.where(ok, disc, 0.0))
            r = np.where((np.abs(a) > 1e-14 * (np.abs(b) + 1e-300))[:, None],
                         np.stack([(-b - sq) / (2 * a), (-b + sq) / (2 * a)], axis=1),
                         np.stack([-c / b, np.full(K, np.nan)], axis=1))
        cuts = np.where(ok[:, None] & (r > 0) & (r < 1), r, np.nan)
    bounds = np.sort(np.column_stack([np.zeros(K), cuts, np.ones(K)]), axis=1)  # NaN last
    bounds = np.where(np.isnan(bounds), 1.0, bounds)
    xg, wg = _GAUSS
    lo, hi = bounds[:, :-1], bounds[:, 1:]  # (K, 3) pieces
    s = lo[..., None] + (hi - lo)[..., None] * (xg + 1.0) / 2.0  # (K, 3, G)
    w = (hi - lo)[..., None] * wg / 2.0
    x = A[:, :, None, None] * s**2 + B[:, :, None, None] * s + X[:, 0, :, None, None]
    dx = 2.0 * A[:, :, None, None] * s + B[:, :, None, None]  # (2, K, 3, G)
    rot = np.stack([dx[1], -dx[0]])  # the tangent turned: |rot| = |dx/ds|
    c = np.asarray(center, dtype=float).reshape(2, 1, 1, 1)
    sign = np.sign(np.sum(rot * (x - c), axis=0))
    length = np.hypot(rot[0], rot[1])
    n = sign * rot / np.where(length > 0, length, 1.0)
    t = traction(x, n)  # (2, K, 3, G)
    shape = np.stack([(1 - s) * (1 - 2 * s), 4 * s * (1 - s), s * (2 * s - 1)])  # (3, K, 3, G)
    nodal = np.einsum("ikpg,ckpg,kpg->cik", shape, t, w * length)  # (2, 3, K)
    f = np.zeros(n_dofs)
    np.add.at(f, dof_of_node[:, tri].reshape(2, -1), nodal.reshape(2, -1))
    return f


def pressure_load(body, ring: np.ndarray, center, table: float | None, unit_weight: float) -> np.ndarray:
    """Hydrostatic water pressure pushing on a body's boundary ``ring`` facing away from the
    tunnel axis (the lining's extrados): full-DOF load (N/m)."""
    def traction(x, n):
        return -hydrostatic(x[1], table, unit_weight) * n

    return boundary_load(body.mesh.p, body.dof_of_node, body.basis.N, ring, center, traction, table)


def effective_release(body, ring: np.ndarray, center, table: float | None, unit_weight: float,
                      k0_of: callable) -> np.ndarray:
    """What the water adds to the excavation load so that it releases the effective traction
    σ′0·n instead of the total σ0·n: ``-∮ diag(K0 u0, u0) n · v`` on the excavation boundary
    (``n`` out of the ground, towards the axis; ``k0_of(x)`` the K0 of the layer at points x)."""
    def traction(x, n_out):  # n_out points away from the axis, into the ground
        u = hydrostatic(x[1], table, unit_weight)
        return np.stack([k0_of(x) * u * n_out[0], u * n_out[1]])

    return boundary_load(body.mesh.p, body.dof_of_node, body.basis.N, ring, center, traction, table)


@dataclass(frozen=True)
class Seepage:
    """Steady seepage towards a drained excavation.

    head : (N,) m, the hydraulic head at the ground's nodes (elevation + p/γw);
    pore : (N,) Pa, pore pressure (≥ 0; zero on the excavation boundary and above the table);
    inflow : m³/s per metre, into the whole tunnel (both halves).
    """

    head: np.ndarray
    pore: np.ndarray
    inflow: float


class SeepageModel:
    """The head problem ``div(k grad h) = 0`` on the ground's P2 mesh for one table depth and
    set of permeabilities (its factorization kept for reuse).

    Fixed head: the water table's ``h = -table`` at every node at or above the table (the
    table line bounds the saturated ground; the ground above it is dry) and on the model's
    side below it (hydrostatic far field); ``h = y`` (zero pore pressure) on the excavation
    boundary. No flow across the bottom and the symmetry line.
    """

    def __init__(self, mesh, hole_nodes: np.ndarray, conductivity: np.ndarray, table: float, width: float,
                 height: float):
        from skfem import Basis, BilinearForm, ElementTriP2

        m = mesh.skfem_mesh()
        self.basis = Basis(m, ElementTriP2(), intorder=4)
        k = np.asarray(conductivity, dtype=float)[:, None]

        @BilinearForm
        def darcy(u, v, w):
            return k * (u.grad[0] * v.grad[0] + u.grad[1] * v.grad[1])

        A = darcy.assemble(self.basis).tocsr()
        x, y = mesh.p
        scale = max(width, height)
        self.table, self.hole = table, np.asarray(hole_nodes)
        fixed = np.zeros(x.size, bool)
        fixed[self.hole] = True
        fixed |= y >= -table - 1e-12 * scale
        fixed |= np.abs(x - width) <= 1e-9 * scale
        self.fixed_head = np.where(np.isin(np.arange(x.size), self.hole), y, -table)
        self.fixed = fixed
        self.free = np.flatnonzero(~fixed)
        self.A = A
        A_ff = A[self.free][:, self.free].tocsr()
        self._coupling = A[self.free][:, np.flatnonzero(fixed)].tocsr()
        order = nested_dissection(m, self.free)
        self._factor = Cholesky(A_ff, order)
        self.y = y

    def solve(self, unit_weight: float) -> Seepage:
        h = self.fixed_head.copy()
        rhs = -(self._coupling @ h[self.fixed])
        f = self._factor
        z = f.solve(_SYS_LT, f.solve(_SYS_L, rhs[f.perm]))
        h[self.free[f.perm]] = z
        # the flux into the tunnel: the discrete reactions at the excavation's fixed nodes
        reaction = self.A[self.hole] @ h
        inflow = -2.0 * float(np.sum(reaction))
        pore = np.maximum(unit_weight * (h - self.y), 0.0)
        pore[self.hole] = 0.0
        return Seepage(head=h, pore=pore, inflow=inflow)


def seepage_load(vector_basis, scalar_basis, delta_p: np.ndarray) -> np.ndarray:
    """Full-DOF load (N/m) of a pore-pressure change ``delta_p`` (scalar P2 nodal values, Pa) on
    the ground's skeleton: the seepage force ``-∫ ∇Δp · v dΩ``."""
    from skfem import LinearForm, asm

    dp = scalar_basis.interpolate(delta_p)

    @LinearForm
    def force(v, w):
        return -(w.dp.grad[0] * v[0] + w.dp.grad[1] * v[1])

    return asm(force, vector_basis, dp=dp)

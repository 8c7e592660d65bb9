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
import scipy.sparse as sp

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
    """Steady unconfined seepage towards a drained excavation (SPEC §1.4, §9.2).

    head : (N,) m, the hydraulic head at the ground's nodes (elevation + p/γw);
    pore : (N,) Pa, pore pressure: γw (h - y) where the ground is saturated, zero where it is dry
        (above the phreatic surface, where the solve's pressure is a suction) and on the drain;
    inflow : m³/s per metre, into the whole tunnel (both halves);
    outflow : m³/s per metre, what enters the model across its held boundaries (both halves):
        equal to ``inflow`` at steady state;
    iterations : Picard iterations of the relative permeability.
    """

    head: np.ndarray
    pore: np.ndarray
    inflow: float
    outflow: float
    iterations: int


#: Relative permeability of dry ground (above the phreatic surface), reached log-linearly over
#: :data:`SUCTION_RANGE` of suction head (PLAXIS's saturated-flow default: 1e-4 over 0.7 m).
DRY_PERMEABILITY = 1e-4
SUCTION_RANGE = 0.7  # m

#: Picard iterations stop when no saturated node's pressure head changes by more than this (m,
#: about 1 Pa) and the drain's set of discharging nodes is unchanged; each iterate is relaxed
#: (without, the phreatic surface flips between elements from one iteration to the next).
HEAD_TOLERANCE = 1e-4
RELAXATION = 0.6
MAX_ITERATIONS = 200


def relative_permeability(suction_head: np.ndarray) -> np.ndarray:
    """k_r of pressure head ``ψ = h - y`` (m): 1 where ψ ≥ 0, log-linear down to
    :data:`DRY_PERMEABILITY` at ``ψ = -SUCTION_RANGE`` and below."""
    psi = np.minimum(np.asarray(suction_head, dtype=float), 0.0)
    return np.maximum(10.0 ** (-np.log10(1.0 / DRY_PERMEABILITY) * (-psi) / SUCTION_RANGE), DRY_PERMEABILITY)


class SeepageModel:
    """Unconfined steady seepage ``div(k k_r(ψ) grad h) = 0`` on the ground's P2 mesh for one
    table depth and set of permeabilities (solved once, on first use, and kept).

    Held head ``h = -table`` on the model's side below the table (the undisturbed far field)
    and, for a table at the surface, on the surface (ponded ground). The drain is a seepage
    face: ``h = y`` (zero pressure) where water leaves the ground into the tunnel, no flow
    where it would enter (there the ground is dry, ψ ≤ 0). No flow across the bottom, the
    symmetry line and the rest of the side and surface. The phreatic surface is where
    ``ψ = 0``: above it ``k_r`` (:func:`relative_permeability`) all but stops the flow, so no
    water crosses it and the ground there is dry. Picard iterations on ``k_r``, each a
    Cholesky solve of the head Laplacian scaled per quadrature point.
    """

    def __init__(self, mesh, hole_nodes: np.ndarray, conductivity: np.ndarray, table: float, width: float,
                 height: float):
        from skfem import Basis, ElementTriP2

        m = mesh.skfem_mesh()
        self.basis = Basis(m, ElementTriP2(), intorder=4)
        x, y = mesh.p
        scale = max(width, height)
        self.table, self.hole, self.y = table, np.asarray(hole_nodes), y
        held = (np.abs(x - width) <= 1e-9 * scale) & (y <= -table + 1e-12 * scale)
        if table <= 0.0:
            held |= y >= -1e-12 * scale
        self.held = np.flatnonzero(held)
        self.unknown = np.flatnonzero(~held)
        self._conductivity = np.asarray(conductivity, dtype=float)
        self._local, rows, cols = _local_matrices(self.basis)
        self._pattern = _Pattern(rows, cols, y.size, self.unknown)
        self._order = nested_dissection(m, self.unknown)
        self._factor: Cholesky | None = None
        self._y_q = self.basis.global_coordinates().value[1]
        self._solution = None

    def matrix(self, kr: np.ndarray):
        """The conductivity matrix (CSR, all nodes) with relative permeability ``kr`` (E, Q)."""
        w = self._conductivity[:, None] * kr
        data = np.matmul(w[:, None, :], self._local)[:, 0, :].T  # (36, E): entry (i, j) of each element
        q, n = self._pattern, self.y.size
        return sp.csr_matrix((np.bincount(q.position, weights=data.ravel(), minlength=q.indices.size), q.indices,
                              q.indptr), shape=(n, n))

    def kr_of(self, head: np.ndarray) -> np.ndarray:
        """(E, Q) relative permeability of the head field ``head``."""
        return relative_permeability(self.basis.interpolate(head).value - self._y_q)

    def solve(self, unit_weight: float) -> Seepage:
        if self._solution is None:
            self._solution = self._picard()
        h, inflow, outflow, iterations = self._solution
        pore = np.maximum(unit_weight * (h - self.y), 0.0)
        pore[self.hole] = 0.0
        return Seepage(head=h, pore=pore, inflow=inflow, outflow=outflow, iterations=iterations)

    def _picard(self):
        h = np.full(self.y.size, -self.table, dtype=float)
        drain = np.ones(self.hole.size, bool)  # discharging (held at h = y) drain nodes
        kr = np.ones_like(self._y_q)
        for it in range(1, MAX_ITERATIONS + 1):
            A = self.matrix(kr)
            new = self._linear(A, drain)
            reaction = (A @ new)[self.hole]
            # the saturated ground's pressure head: what the result keeps (the dry ground's is zero)
            change = float(np.max(np.abs(np.maximum(new - self.y, 0.0) - np.maximum(h - self.y, 0.0))))
            h = new if it == 1 else h + RELAXATION * (new - h)
            # seepage face: release held nodes that would feed the ground, hold free ones under pressure
            now = np.where(drain, reaction <= 0.0, h[self.hole] >= self.y[self.hole])
            if change <= HEAD_TOLERANCE and np.array_equal(now, drain) and it > 1:
                h = new
                break
            drain, kr = now, self.kr_of(h)
        else:
            from ..errors import SolverError

            raise SolverError(f"water: the unconfined seepage did not converge in {MAX_ITERATIONS} iterations")
        inflow = -2.0 * float(np.sum(reaction[drain]))
        outflow = 2.0 * float(np.sum((A @ h)[self.held]))
        return h, inflow, outflow, it

    def _linear(self, A, drain: np.ndarray) -> np.ndarray:
        """Heads with ``A``: held on the far field, ``h = y`` at the discharging drain nodes."""
        n = self.y.size
        fixed = np.zeros(n, bool)
        fixed[self.held] = True
        fixed[self.hole[drain]] = True
        h = np.zeros(n)
        h[self.held] = -self.table
        h[self.hole[drain]] = self.y[self.hole[drain]]
        rhs = -(A @ np.where(fixed, h, 0.0))
        u = self.unknown
        K = self._pattern.unknown_block(A, fixed[u])
        b = np.where(fixed[u], h[u], rhs[u])
        if self._factor is None:  # the one pattern: ordered and analysed once, refactorized after
            self._factor = Cholesky(K, self._order)
        else:
            self._factor.refactor(K)
        f = self._factor
        h[u[f.perm]] = f.solve(_SYS_LT, f.solve(_SYS_L, b[f.perm]))
        return h


class _Pattern:
    """The CSR pattern of the conductivity matrix (each element entry's ``position`` in it) and of
    its block on the ``unknown`` nodes (held at one pattern whichever drain nodes are held: a
    held node's row and column are zeroed but kept, its diagonal set to 1)."""

    def __init__(self, rows: np.ndarray, cols: np.ndarray, n: int, unknown: np.ndarray):
        keys, self.position = np.unique(rows.astype(np.int64) * n + cols, return_inverse=True)
        r, c = keys // n, keys % n
        self.indices = c.astype(np.int32)
        self.indptr = np.r_[0, np.cumsum(np.bincount(r, minlength=n))].astype(np.int32)
        local = np.full(n, -1)
        local[unknown] = np.arange(unknown.size)
        self.block = np.flatnonzero((local[r] >= 0) & (local[c] >= 0))  # sorted by (row, column) still
        self.block_row, self.block_col = local[r[self.block]], local[c[self.block]]
        self.block_shape = (unknown.size, unknown.size)
        self._block = sp.csr_matrix((np.zeros(self.block.size), self.block_col,
                                     np.r_[0, np.cumsum(np.bincount(self.block_row, minlength=unknown.size))]),
                                    shape=self.block_shape)

    def unknown_block(self, A, fixed: np.ndarray):
        """``A``'s block on the unknown nodes, the ``fixed`` ones' rows and columns replaced by identity."""
        data = A.data[self.block].copy()
        touched = fixed[self.block_row] | fixed[self.block_col]
        data[touched] = 0.0
        data[touched & (self.block_row == self.block_col)] = 1.0
        K = self._block.copy()
        K.data = data
        return K


def _local_matrices(basis):
    """(E, Q, 36) per-quadrature-point element matrices ``w |J| ∇φi·∇φj`` of a P2 basis (entry
    ``6 i + j``), and the global row and column of each (6, 6, E) entry."""
    grads = np.stack([basis.basis[i][0].grad for i in range(basis.Nbfun)])  # (6, 2, E, Q)
    local = np.einsum("ideq,jdeq,eq->eqij", grads, grads, basis.dx, optimize=True)
    local = np.ascontiguousarray(local.reshape(local.shape[0], local.shape[1], -1))
    dofs = basis.element_dofs  # (6, E)
    rows = np.broadcast_to(dofs[:, None, :], (dofs.shape[0],) * 2 + dofs.shape[1:]).ravel()
    cols = np.broadcast_to(dofs[None, :, :], (dofs.shape[0],) * 2 + dofs.shape[1:]).ravel()
    return local, rows, cols


@dataclass(frozen=True)
class PhreaticSampler:
    """The verticals above surface points ``x`` sampled for the phreatic surface: depths ``z`` (K,)
    below the surface, ``A`` (n K, N) the P2 interpolation of a head field at the samples (vertical i,
    depth k at row i K + k) and ``open`` (n, K) the samples that can be wet: inside a triangle (the
    straight-sided ones) and clear of the excavation. Geometry alone: built once for a model's mesh
    (:func:`phreatic_sampler`), it gives every case's phreatic surface with one product
    (:meth:`depth`)."""

    z: np.ndarray
    A: sp.csr_matrix
    open: np.ndarray

    def depth(self, head: np.ndarray) -> np.ndarray:
        """Depth (m below the surface) of the phreatic surface above each point: the topmost sample
        where the pressure head ``h - y`` of the P2 field ``head`` is ≥ 0, linear from the dry sample
        above it; NaN where the vertical is dry to the model's bottom."""
        n, K = self.open.shape
        psi = np.where(self.open, (self.A @ head).reshape(n, K) + self.z, -np.inf)
        wet = psi >= 0.0
        rows = np.flatnonzero(wet.any(axis=1))
        k = np.argmax(wet[rows], axis=1)  # the first wet sample from the surface down
        above = psi[rows, np.maximum(k - 1, 0)]
        between = (k > 0) & np.isfinite(above)  # a dry sample above it: linear between the two
        z0, z1, now = self.z[np.maximum(k - 1, 0)], self.z[k], psi[rows, k]
        out = np.full(n, np.nan)
        out[rows] = np.where(between, z0 + (z1 - z0) * -above / np.where(between, now - above, 1.0), z1)
        return out


def phreatic_sampler(mesh, x: np.ndarray, *, height: float, center, radius: float, step: float) -> PhreaticSampler:
    """The :class:`PhreaticSampler` of the verticals at ``x`` (m) on the ground's P2 ``mesh``
    (:class:`~solver.geometry.mesh.BodyMesh`), samples ``step`` m apart down to ``height``; the
    excavation (``radius`` about ``center``) is dry. The samples are located in the straight-sided
    triangles and keep clear of the curved excavation edges."""
    z = np.linspace(0.0, height, max(2, int(np.ceil(height / step)) + 1))
    x = np.asarray(x, dtype=float)
    rows, cols, vals = [], [], []
    able = np.zeros((x.size, z.size), bool)
    for i, xc in enumerate(x):
        found, nodes, shape = _column_samples(mesh, xc, z)
        able[i] = found & (np.hypot(xc - center[0], -z - center[1]) >= radius + 0.5 * step)
        k = np.flatnonzero(found)
        rows.append(np.repeat(i * z.size + k, 6))
        cols.append(nodes[:, k].T.ravel())
        vals.append(shape[:, k].T.ravel())
    A = sp.csr_matrix((np.concatenate(vals), (np.concatenate(rows), np.concatenate(cols))),
                      shape=(x.size * z.size, mesh.p.shape[1]))
    return PhreaticSampler(z, A, able)


def _column_samples(mesh, xc: float, z: np.ndarray):
    """Where the points ``(xc, -z)`` lie in the P2 mesh: whether each is inside a triangle (K,), the
    six nodes (6, K) and P2 shape values (6, K) of the first triangle holding it."""
    p, t = mesh.p, mesh.t
    xv = p[0, t[:3]]  # (3, E)
    near = np.flatnonzero((xv.min(axis=0) <= xc + 1e-12) & (xv.max(axis=0) >= xc - 1e-12))
    P = p[:, t[:3, near]]  # (2, 3, e)
    d1, d2 = P[:, 1] - P[:, 0], P[:, 2] - P[:, 0]
    det = d1[0] * d2[1] - d1[1] * d2[0]
    rx, ry = xc - P[0, 0][:, None], -z[None, :] - P[1, 0][:, None]  # (e, K)
    l1 = (d2[1][:, None] * rx - d2[0][:, None] * ry) / det[:, None]
    l2 = (-d1[1][:, None] * rx + d1[0][:, None] * ry) / det[:, None]
    l0 = 1.0 - l1 - l2
    inside = (l0 >= -1e-10) & (l1 >= -1e-10) & (l2 >= -1e-10)
    found = inside.any(axis=0)
    e = np.argmax(inside, axis=0)  # the first triangle holding each sample
    k = np.arange(z.size)
    a, b, c = l0[e, k], l1[e, k], l2[e, k]
    shape = np.stack([a * (2 * a - 1), b * (2 * b - 1), c * (2 * c - 1), 4 * a * b, 4 * b * c, 4 * a * c])
    return found, t[:, near[e]], shape


def seepage_load(vector_basis, scalar_basis, delta_p: np.ndarray) -> np.ndarray:
    """Full-DOF load (N/m) of a pore-pressure change ``delta_p`` (scalar P2 nodal values, Pa) on
    the ground's skeleton: the seepage force ``-∫ ∇Δp · v dΩ``."""
    from skfem import LinearForm, asm

    dp = scalar_basis.interpolate(delta_p)

    @LinearForm
    def force(v, w):
        return -(w.dp.grad[0] * v[0] + w.dp.grad[1] * v[1])

    return asm(force, vector_basis, dp=dp)

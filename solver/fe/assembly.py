"""Plane-strain linear elasticity of each body with scikit-fem (isoparametric P2 triangles).

Each body is assembled on its own mesh; the two meet only through the interface
operators built in :mod:`solver.fe.flexibility`. A :class:`Body` holds what its mesh,
material and essential conditions fix (basis, stiffness on the free DOFs); loads are
assembled separately (:func:`gravity_load`, :func:`surface_load`, ...) because they
change from stage to stage and case to case.

Quadrature: degree 4 on every element, which integrates the P2 stiffness on curved
(quadratic) triangles with a geostatic stress that is linear in y exactly, so the
discrete in-situ state is in exact equilibrium (:func:`initial_stress_forces`).
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import scipy.sparse as sp
from skfem import Basis, BilinearForm, ElementTriP2, ElementVector, FacetBasis, LinearForm, asm
from skfem.models.elasticity import lame_parameters

from ..geometry.bodies import BodyMesh

#: Quadrature degree (exact for the geostatic equilibrium on quadratic geometry, see above).
INTORDER = 4

#: Reference coordinates of the centroids of the four corner sub-triangles of a P2
#: triangle (corners 0-01-02, 01-1-12, 02-12-2, 01-12-02): where face stresses are reported.
SUBTRIANGLE_CENTROIDS = np.array([[1 / 6, 2 / 3, 1 / 6, 1 / 3], [1 / 6, 1 / 6, 2 / 3, 1 / 3]])
#: The sub-triangles as local node indices of the 6-node triangle (counter-clockwise).
SUBTRIANGLES = np.array([[0, 3, 5], [3, 1, 4], [5, 4, 2], [3, 4, 5]])


@dataclass(frozen=True)
class Body:
    """One elastic body: its P2 basis and stiffness, condensed on the essential conditions.

    Attributes
    ----------
    mesh : the body's quadratic triangles.
    basis : scikit-fem vector P2 basis (degree-4 quadrature).
    dof_of_node : (2, N) full DOF of component c at node j.
    free : (n,) the full DOFs that are unknowns.
    free_of : (2, N) free-DOF index of component c at node j, -1 where constrained.
    K : (n, n) CSR stiffness on the free DOFs (N/m per m of tunnel), in the unknowns' basis.
    skew : the nodes whose unknowns are turned (:func:`assemble_body`'s ``skew``) as a
        :class:`PairRotation` ``T`` of the free DOFs: ``u_xy = T u``; None if none is.
        The free-DOF vectors of the body (``K``'s unknowns, :meth:`restrict`'s loads,
        :meth:`expand`'s input) are in that basis; nodal fields are in x, y.
    """

    mesh: BodyMesh
    basis: Basis
    dof_of_node: np.ndarray
    free: np.ndarray
    free_of: np.ndarray
    K: sp.csr_matrix
    skew: PairRotation | None = None

    @property
    def n(self) -> int:
        return self.free.size

    def restrict(self, f_full: np.ndarray) -> np.ndarray:
        """Free-DOF part of a full (x, y) load or displacement vector, in the unknowns' basis
        (``Tᵀ f``: ``T`` is orthogonal, so loads and displacements turn alike)."""
        f = np.asarray(f_full)[self.free]
        return f if self.skew is None else self.skew.apply_transpose(f)

    def expand(self, u_free: np.ndarray) -> np.ndarray:
        """Nodal displacements (2, N) in x, y from free-DOF values (constrained DOFs are 0)."""
        if self.skew is not None:
            u_free = self.skew.apply(u_free)
        u = np.zeros(self.free_of.shape)
        mask = self.free_of >= 0
        u[mask] = u_free[self.free_of[mask]]
        return u

    def full(self, u_nodes: np.ndarray) -> np.ndarray:
        """Full DOF vector of nodal displacements (2, N)."""
        x = np.zeros(self.basis.N)
        x[self.dof_of_node] = u_nodes
        return x

    def node_of_dof(self) -> np.ndarray:
        """(n,) mesh node of each free DOF."""
        out = np.empty(self.n, np.int64)
        nodes = np.broadcast_to(np.arange(self.free_of.shape[1]), self.free_of.shape)
        mask = self.free_of >= 0
        out[self.free_of[mask]] = nodes[mask]
        return out

    def rigid_vertical(self) -> np.ndarray:
        """Free-DOF vector of the rigid upward translation u_y = 1 (the lining's zero mode)."""
        r = np.zeros(self.n)
        ys = self.free_of[1]
        r[ys[ys >= 0]] = 1.0
        return r if self.skew is None else self.skew.apply_transpose(r)


class PairRotation:
    """An orthogonal ``T`` (n, n) that turns pairs of unknowns ``(a_i, b_i)`` by angles
    ``(cos, sin) = (c_i, s_i)``: ``u_a = c u'_a - s u'_b``, ``u_b = s u'_a + c u'_b`` (the
    pair ``u'`` of a node's x and y unknowns becomes, e.g., its normal and tangential
    components); the identity elsewhere. Applied pair by pair, never as a product."""

    def __init__(self, n: int, a: np.ndarray, b: np.ndarray, c: np.ndarray, s: np.ndarray):
        self.n = n
        self.a, self.b = np.asarray(a, dtype=np.int64), np.asarray(b, dtype=np.int64)
        self.c, self.s = np.asarray(c, dtype=float), np.asarray(s, dtype=float)

    def matrix(self) -> sp.csr_matrix:
        """``T`` as a sparse matrix."""
        diag = np.ones(self.n)
        diag[self.a] = diag[self.b] = self.c
        return sp.csr_matrix((np.r_[diag, self.s, -self.s],
                              (np.r_[np.arange(self.n), self.b, self.a], np.r_[np.arange(self.n), self.a, self.b])),
                             shape=(self.n, self.n))

    def _turn(self, x: np.ndarray, sign: float) -> np.ndarray:
        x = np.array(x, dtype=float)
        xa, xb = x[self.a], x[self.b]
        c = self.c.reshape((-1,) + (1,) * (x.ndim - 1))
        s = sign * self.s.reshape(c.shape)
        x[self.a], x[self.b] = c * xa - s * xb, s * xa + c * xb
        return x

    def apply(self, x: np.ndarray) -> np.ndarray:
        """``T x`` for a vector or an (n, j) block."""
        return self._turn(x, 1.0)

    def apply_transpose(self, x: np.ndarray) -> np.ndarray:
        """``Tᵀ x``."""
        return self._turn(x, -1.0)


def vector_basis(mesh: BodyMesh) -> Basis:
    """Vector P2 basis on the isoparametric mesh."""
    return Basis(mesh.skfem_mesh(), ElementVector(ElementTriP2()), intorder=INTORDER)


def _dof_of_node(basis: Basis) -> np.ndarray:
    return np.hstack([basis.nodal_dofs, basis.facet_dofs])


def _near(values: np.ndarray, target: float, scale: float) -> np.ndarray:
    return np.abs(values - target) <= 1e-9 * scale


def assemble_body(mesh: BodyMesh, young: float, poisson: float, fixed: list[np.ndarray],
                  basis: Basis | None = None,
                  skew: tuple[np.ndarray, np.ndarray] | None = None) -> Body:
    """Stiffness of one body with the full DOFs in ``fixed`` removed.

    ``skew = (nodes, directions)``, directions (2, k) unit vectors: at these nodes (those
    with both DOFs free) the unknowns are the displacement's components along the
    direction and across it (the direction turned 90° counter-clockwise), a nodal skew
    basis: with the interface normals, each contact row acts on one unknown. The element
    stiffnesses of the elements at those nodes are turned before they are summed
    (``Rᵀ K_e R``), which costs a few hundred small element matrices instead of a pass
    over ``K``.
    """
    basis = vector_basis(mesh) if basis is None else basis
    coo = elasticity_form(young, poisson).elemental(basis)
    dof_of_node = _dof_of_node(basis)
    is_fixed = np.zeros(basis.N, bool)
    for dofs in fixed:
        is_fixed[dofs] = True
    free = np.flatnonzero(~is_fixed)
    index = -np.ones(basis.N, np.int64)
    index[free] = np.arange(free.size)
    free_of = index[dof_of_node]
    rotation = None
    if skew is not None:
        nodes, directions = np.asarray(skew[0]), np.asarray(skew[1], dtype=float)
        both = (free_of[0, nodes] >= 0) & (free_of[1, nodes] >= 0)
        nodes, c, s = nodes[both], directions[0, both], directions[1, both]
        if not np.allclose(np.hypot(c, s), 1.0, rtol=0, atol=1e-12):
            raise ValueError("skew directions must be unit vectors (the turn must be orthogonal)")
        _turn_elements(coo, basis, dof_of_node[:, nodes], c, s)
        rotation = PairRotation(free.size, free_of[0, nodes], free_of[1, nodes], c, s)
    K = _structural_csr(coo)[free][:, free].tocsr()
    return Body(mesh=mesh, basis=basis, dof_of_node=dof_of_node, free=free, free_of=free_of, K=K,
                skew=rotation)


def _turn_elements(coo, basis: Basis, dofs: np.ndarray, c: np.ndarray, s: np.ndarray) -> None:
    """``Rᵀ K_e R`` in place in scikit-fem's element data, for the elements with a node whose
    full x, y DOFs ``dofs[:, i]`` turn by ``(c_i, s_i)`` (:class:`PairRotation`'s convention).

    The vector P2 element numbers a node's x and y DOFs side by side (local 2k, 2k + 1);
    that is checked on every element turned."""
    nb, ne = basis.Nbfun, basis.nelems
    data = coo.data.reshape(nb, nb, ne)  # [trial j, test i, element]: a view
    E = basis.element_dofs  # (nb, ne) full DOF of each local DOF
    turn_x, turn_y = np.full(basis.N, -1, np.int64), np.full(basis.N, -1, np.int64)
    turn_x[dofs[0]] = turn_y[dofs[1]] = np.arange(dofs.shape[1])
    elements = np.flatnonzero((turn_x[E] >= 0).any(axis=0))
    if elements.size == 0:
        return
    local = E[:, elements]
    t = turn_x[local[0::2]]  # (nb/2, elements): the turn of each local node, -1 for none
    if not (np.array_equal(turn_y[local[1::2]], t) and np.all(turn_x[local[1::2]] < 0)):
        raise AssertionError("unexpected local DOF layout of the vector P2 element")
    cs, sn = np.where(t >= 0, c[t], 1.0), np.where(t >= 0, s[t], 0.0)
    block = data[:, :, elements]  # a contiguous copy
    pairs = nb // 2
    rows = block.reshape(pairs, 2, nb, -1)  # rows, then columns: Rᵀ K_e R
    a, b = rows[:, 0].copy(), rows[:, 1].copy()
    rows[:, 0], rows[:, 1] = cs[:, None] * a + sn[:, None] * b, cs[:, None] * b - sn[:, None] * a
    cols = block.reshape(nb, pairs, 2, -1)
    a, b = cols[:, :, 0].copy(), cols[:, :, 1].copy()
    cols[:, :, 0], cols[:, :, 1] = cs * a + sn * b, cs * b - sn * a
    data[:, :, elements] = block


def ground_constraints(basis: Basis, *, width: float, height: float, side: str, bottom: str) -> list[np.ndarray]:
    """Full DOFs held by the symmetry line, the bottom and the side (SPEC §1)."""
    dofs = _dof_of_node(basis)
    x, y = basis.doflocs[:, dofs[0]]
    scale = max(width, height)
    fixed = [dofs[0, _near(x, 0.0, scale)]]
    low = _near(y, -height, scale)
    fixed.append(dofs[:, low].ravel() if bottom == "fixed" else dofs[1, low])
    right = _near(x, width, scale)
    if side == "fixed":
        fixed.append(dofs[:, right].ravel())
    elif side == "roller":
        fixed.append(dofs[0, right])
    return fixed


def lining_constraints(basis: Basis, *, scale: float, loose: np.ndarray | None = None) -> list[np.ndarray]:
    """The lining's symmetry line; its vertical translation stays free (it floats). ``loose``:
    nodes on the line that it does not hold (a joint's face there, held by contact instead)."""
    dofs = _dof_of_node(basis)
    x = basis.doflocs[0, dofs[0]]
    on = _near(x, 0.0, scale)
    if loose is not None:
        on[np.asarray(loose, dtype=np.int64)] = False
    return [dofs[0, on]]


def gravity_load(basis: Basis, density: float, g: float, where: np.ndarray | None = None) -> np.ndarray:
    """Consistent nodal body force of density × g downward (full DOFs, N/m); ``where`` (E,)
    bool limits it to some elements (one layer's)."""
    mask = _mask(where)

    @LinearForm
    def load(v, w):
        return -density * g * v[1] if mask is None else -density * g * v[1] * mask

    return asm(load, basis)


def _mask(where: np.ndarray | None) -> np.ndarray | None:
    """(E, 1) 0/1 factor of a per-element selection, broadcast over quadrature points."""
    return None if where is None else np.asarray(where, dtype=float)[:, None]


def _facets(basis: Basis, where) -> FacetBasis:
    mesh = basis.mesh
    return FacetBasis(mesh, basis.elem, facets=mesh.facets_satisfying(where), intorder=INTORDER)


def surface_load(basis: Basis, q: float, *, scale: float) -> np.ndarray:
    """Uniform downward pressure ``q`` (Pa) on the ground surface y = 0 (full DOFs)."""

    @LinearForm
    def load(v, w):
        return -q * v[1]

    return asm(load, _facets(basis, lambda x: _near(x[1], 0.0, scale)))


def side_pressure_load(basis: Basis, *, q: float, rho_g: float, k0: float, width: float,
                       scale: float, depths: tuple[float, float] | None = None) -> np.ndarray:
    """Horizontal pressure K0 × geostatic vertical stress on the side x = width (full DOFs).

    ``depths = (top, bottom)`` (m below the surface) loads only that stretch of the side (one
    layer), with the vertical stress ``q + ρg (z - top)`` from its top."""
    if depths is None:
        @LinearForm
        def load(v, w):
            return -k0 * (q - rho_g * w.x[1]) * v[0]

        return asm(load, _facets(basis, lambda x: _near(x[0], width, scale)))
    top, bottom = depths

    @LinearForm
    def layer_load(v, w):
        return -k0 * (q - rho_g * (w.x[1] + top)) * v[0]

    return asm(layer_load, _facets(basis, lambda x: _near(x[0], width, scale) & (-x[1] >= top) & (-x[1] <= bottom)))


def geostatic_stress(y: np.ndarray, *, q: float, rho_g: float, k0: float) -> tuple[np.ndarray, np.ndarray]:
    """σ0_xx (= σ0_zz) and σ0_yy (Pa, tension positive) at depth -y (SPEC §1.1); σ0_xy = 0."""
    syy = -(q - rho_g * y)
    return k0 * syy, syy


def initial_stress_forces(basis: Basis, *, q: float, rho_g: float, k0: float,
                          vertical: float = 1.0, top: float = 0.0, where: np.ndarray | None = None) -> np.ndarray:
    """Internal nodal forces of the geostatic stress, ∫ Bᵀ σ0 dΩ (full DOFs, N/m).

    ``vertical`` scales σ0_yy alone (1 for the geostatic state; 0 with k0 = 1 gives the
    part of σ0_xx, so that ``∫Bᵀσ0 = K0 · [xx part] + [yy part]`` for any K0). ``where`` (E,)
    bool limits the integral to some elements (one layer's), whose vertical stress is
    ``q + ρg (z - top)`` from the layer's ``top`` (m below the surface).
    """
    if where is None and top == 0.0:
        @LinearForm
        def internal(v, w):
            sxx, syy = geostatic_stress(w.x[1], q=q, rho_g=rho_g, k0=k0)
            return sxx * v.grad[0][0] + vertical * syy * v.grad[1][1]

        return asm(internal, basis)
    mask = _mask(where)

    @LinearForm
    def layer_internal(v, w):
        sxx, syy = geostatic_stress(w.x[1] + top, q=q, rho_g=rho_g, k0=k0)
        work = sxx * v.grad[0][0] + vertical * syy * v.grad[1][1]
        return work if mask is None else work * mask

    return asm(layer_internal, basis)


def point_basis(body: Body, points: np.ndarray = SUBTRIANGLE_CENTROIDS) -> Basis:
    """The body's basis evaluated at reference ``points`` (2, P) of every element (no weights)."""
    W = np.full(points.shape[1], 0.5 / points.shape[1])  # unused: only point values are read
    return Basis(body.basis.mesh, body.basis.elem, quadrature=(points, W))


def _gradient_rows(basis: Basis) -> tuple[np.ndarray, np.ndarray]:
    """``(values, dofs)`` (4 E Q, w) of the displacement gradient at the points of ``basis`` on the full
    DOF vector, row by row: row ``(i, j, e, q)`` of ``du_i/dx_j`` (flattened) holds the ``w`` basis functions
    of element ``e`` that move component ``i`` (each vector basis function moves one)."""
    dofs = basis.element_dofs  # (Nbfun, E)
    E, Q = basis.dx.shape
    grads = [basis.basis[k][0].grad for k in range(basis.Nbfun)]  # (2, 2, E, Q): one component non-zero
    comp = np.array([0 if np.any(g[0]) else 1 for g in grads])
    values, at = [], []
    for c in (0, 1):
        ks = np.flatnonzero(comp == c)
        values.append(np.stack([grads[k][c] for k in ks], axis=-1))  # (2, E, Q, w)
        at.append(np.broadcast_to(dofs[ks].T[None, :, None, :], (2, E, Q, ks.size)))
    return np.stack(values).reshape(4 * E * Q, -1), np.stack(at).reshape(4 * E * Q, -1)


def _rows_to_csr(values: np.ndarray, columns: np.ndarray, width: int) -> sp.csr_matrix:
    """A CSR matrix of ``w`` entries a row (``values``, ``columns``: (rows, w)), built as it is stored."""
    r, w = values.shape
    return sp.csr_matrix((values.ravel(), columns.ravel(), np.arange(0, r * w + 1, w)), shape=(r, width))


def nodal_gradient_operator(basis: Basis) -> sp.csr_matrix:
    """The displacement gradient at the points of ``basis`` as a sparse operator on the full DOF
    vector (:meth:`Body.full` of the nodal displacements): ``(G @ x).reshape(2, 2, E, P)`` is
    scikit-fem's ``basis.interpolate(x).grad`` at a tenth of its cost once built (a model's stored
    stresses, :func:`stress_at`)."""
    values, dofs = _gradient_rows(basis)
    return _rows_to_csr(values, dofs, basis.N)


def gradient_operator(body: Body, basis: Basis) -> sp.csr_matrix:
    """The displacement gradient at the quadrature points of ``basis`` as a sparse operator on
    ``body``'s unknowns: ``(G @ x).reshape(2, 2, E, Q)`` is ``du_i/dx_j`` of the free-DOF vector
    ``x`` (in the unknowns' basis). Its transpose integrates: ``Gᵀ w`` with ``w`` a gradient-shaped
    field times the points' weights is ``∫ w : ∇v`` for every test function ``v``.

    Built row by row in the unknowns' numbering (:func:`_gradient_rows`; a constrained DOF's entries
    dropped), then times ``T`` where some nodes' unknowns are turned (``u_xy = T u``)."""
    values, dofs = _gradient_rows(basis)
    unknown = np.full(basis.N, -1, np.int64)
    unknown[body.free] = np.arange(body.free.size)
    cols = unknown[dofs]
    G = _rows_to_csr(np.where(cols >= 0, values, 0.0), np.maximum(cols, 0), body.free.size)
    G.eliminate_zeros()
    return G if body.skew is None else (G @ body.skew.matrix()).tocsr()


def stress_at(body: Body, young, poisson, u_nodes: np.ndarray, points: tuple[int, int],
              gradient: sp.csr_matrix) -> np.ndarray:
    """Stress (4, E, P) in Pa (xx, yy, xy, zz; tension positive) at the ``points`` (E, P) of a
    :func:`point_basis`, through its :func:`nodal_gradient_operator` ``gradient``.

    ``u_nodes`` is the nodal displacement (2, N); plane strain gives
    σ_zz = λ (ε_xx + ε_yy).
    """
    grad = (gradient @ body.full(u_nodes)).reshape((2, 2) + tuple(points))  # du_i/dx_j
    return _hooke(grad, young, poisson)


def _hooke(grad: np.ndarray, young: float, poisson: float) -> np.ndarray:
    return np.stack(_stress_components(grad, young, poisson))


def _stress_components(grad: np.ndarray, young: float, poisson: float) -> tuple[np.ndarray, ...]:
    """Plane-strain Hooke's law: σ_xx, σ_yy, σ_xy, σ_zz from the displacement gradient."""
    lam, mu = lame_parameters(young, poisson)
    exx, eyy = grad[0, 0], grad[1, 1]
    tr = exx + eyy
    return lam * tr + 2 * mu * exx, lam * tr + 2 * mu * eyy, mu * (grad[0, 1] + grad[1, 0]), lam * tr


def _structural_csr(coo) -> sp.csr_matrix:
    """A scikit-fem ``COOData`` as CSR with every element entry kept, exact zeros too:
    ``asm`` drops the zero element entries, which makes the pattern depend on the values
    (at some meshes an x row of a node then misses a column its y row has): structural,
    the pattern is the mesh's alone, whatever the materials and the skew basis."""
    i, j = coo.indices
    return sp.coo_matrix((coo.data, (i, j)), shape=coo.shape).tocsr()


def elasticity_form(young: float, poisson: float) -> BilinearForm:
    """The stiffness form ``∫ σ(u) : ∇v`` with :func:`_stress_components`' plane-strain law
    (the same Hooke's law as the stress recovery). Written out on the gradient's components
    the form assembles 1.7× faster than scikit-fem's generic ``linear_elasticity``
    (``C(sym_grad(u)) : sym_grad(v)``; 0.49 against 0.81 s for the 128k-unknown ground, /tmp
    script; a whole body's assembly 1.5×, README) and agrees with it to 3e-16 of the
    largest entry."""

    @BilinearForm
    def form(u, v, w):
        return _work(_stress_components(u.grad, young, poisson), v.grad)

    return form


def _work(stress, grad) -> np.ndarray:
    """``σ : ∇v`` of a plane-strain stress (xx, yy, xy, ...) against a test gradient (σ symmetric)."""
    return stress[0] * grad[0, 0] + stress[1] * grad[1, 1] + stress[2] * (grad[0, 1] + grad[1, 0])


def element_nodal_forces(body: Body, young: float, poisson: float, u_nodes: np.ndarray,
                         density: float, g: float) -> tuple[np.ndarray, np.ndarray]:
    """Per element and local DOF: internal force ∫ σ:∇φ minus the body-force share ∫ ρ g φ_y.

    Returns ``(force, dof)``, both (12, E): force in N/m and the full DOF of each local DOF.
    The sum over elements of ``force`` at a free DOF is the external (non body-force)
    load there: what the section-equilibrium lining forces are built from.
    """
    basis = body.basis
    grad = basis.interpolate(body.full(u_nodes)).grad
    s = _hooke(grad, young, poisson)
    dx = basis.dx  # (E, Q) quadrature weight × Jacobian
    out = np.empty((basis.Nbfun, basis.nelems))
    for i in range(basis.Nbfun):
        phi = basis.basis[i][0]
        gi = phi.grad
        work = _work(s, gi)
        out[i] = np.sum((work + density * g * np.asarray(phi)[1]) * dx, axis=1)
    return out, basis.element_dofs

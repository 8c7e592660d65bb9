"""Plane-strain linear elasticity of each body with scikit-fem (isoparametric P2 triangles).

Each body is assembled on its own mesh; the two meet only through the interface
operators built in :mod:`solver.flexibility`. A :class:`Body` holds what its mesh,
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

from .mesh import BodyMesh

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
    K : (n, n) CSR stiffness on the free DOFs (N/m per m of tunnel).
    """

    mesh: BodyMesh
    basis: Basis
    dof_of_node: np.ndarray
    free: np.ndarray
    free_of: np.ndarray
    K: sp.csr_matrix

    @property
    def n(self) -> int:
        return self.free.size

    def restrict(self, f_full: np.ndarray) -> np.ndarray:
        """Free-DOF part of a full load vector."""
        return np.asarray(f_full)[self.free]

    def expand(self, u_free: np.ndarray) -> np.ndarray:
        """Nodal displacements (2, N) from free-DOF values (constrained DOFs are 0)."""
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
        return r


def vector_basis(mesh: BodyMesh) -> Basis:
    """Vector P2 basis on the isoparametric mesh."""
    return Basis(mesh.skfem_mesh(), ElementVector(ElementTriP2()), intorder=INTORDER)


def _dof_of_node(basis: Basis) -> np.ndarray:
    return np.hstack([basis.nodal_dofs, basis.facet_dofs])


def _near(values: np.ndarray, target: float, scale: float) -> np.ndarray:
    return np.abs(values - target) <= 1e-9 * scale


def assemble_body(mesh: BodyMesh, young: float, poisson: float, fixed: list[np.ndarray],
                  basis: Basis | None = None) -> Body:
    """Stiffness of one body with the full DOFs in ``fixed`` removed."""
    basis = vector_basis(mesh) if basis is None else basis
    K = _structural_csr(elasticity_form(young, poisson).elemental(basis))
    dof_of_node = _dof_of_node(basis)
    is_fixed = np.zeros(basis.N, bool)
    for dofs in fixed:
        is_fixed[dofs] = True
    free = np.flatnonzero(~is_fixed)
    index = -np.ones(basis.N, np.int64)
    index[free] = np.arange(free.size)
    K = K.tocsr()[free][:, free].tocsr()
    return Body(mesh=mesh, basis=basis, dof_of_node=dof_of_node, free=free,
                free_of=index[dof_of_node], K=K)


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


def lining_constraints(basis: Basis, *, scale: float) -> list[np.ndarray]:
    """The lining's symmetry line; its vertical translation stays free (it floats)."""
    dofs = _dof_of_node(basis)
    x = basis.doflocs[0, dofs[0]]
    return [dofs[0, _near(x, 0.0, scale)]]


def gravity_load(basis: Basis, density: float, g: float) -> np.ndarray:
    """Consistent nodal body force of density × g downward (full DOFs, N/m)."""

    @LinearForm
    def load(v, w):
        return -density * g * v[1]

    return asm(load, basis)


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
                       scale: float) -> np.ndarray:
    """Horizontal pressure K0 × geostatic vertical stress on the side x = width (full DOFs)."""

    @LinearForm
    def load(v, w):
        return -k0 * (q - rho_g * w.x[1]) * v[0]

    return asm(load, _facets(basis, lambda x: _near(x[0], width, scale)))


def geostatic_stress(y: np.ndarray, *, q: float, rho_g: float, k0: float) -> tuple[np.ndarray, np.ndarray]:
    """σ0_xx (= σ0_zz) and σ0_yy (Pa, tension positive) at depth -y (SPEC §1.1); σ0_xy = 0."""
    syy = -(q - rho_g * y)
    return k0 * syy, syy


def initial_stress_forces(basis: Basis, *, q: float, rho_g: float, k0: float,
                          vertical: float = 1.0) -> np.ndarray:
    """Internal nodal forces of the geostatic stress, ∫ Bᵀ σ0 dΩ (full DOFs, N/m).

    ``vertical`` scales σ0_yy alone (1 for the geostatic state; 0 with k0 = 1 gives the
    part of σ0_xx, so that ``∫Bᵀσ0 = K0 · [xx part] + [yy part]`` for any K0).
    """

    @LinearForm
    def internal(v, w):
        sxx, syy = geostatic_stress(w.x[1], q=q, rho_g=rho_g, k0=k0)
        return sxx * v.grad[0][0] + vertical * syy * v.grad[1][1]

    return asm(internal, basis)


def point_basis(body: Body, points: np.ndarray = SUBTRIANGLE_CENTROIDS) -> Basis:
    """The body's basis evaluated at reference ``points`` (2, P) of every element (no weights)."""
    W = np.full(points.shape[1], 0.5 / points.shape[1])  # unused: only point values are read
    return Basis(body.basis.mesh, body.basis.elem, quadrature=(points, W))


def stress_at(body: Body, young: float, poisson: float, u_nodes: np.ndarray,
              basis: Basis | None = None) -> np.ndarray:
    """Stress (4, E, P) in Pa (xx, yy, xy, zz; tension positive) at the points of ``basis``
    (:func:`point_basis`, the sub-triangle centroids by default).

    ``u_nodes`` is the nodal displacement (2, N); plane strain gives
    σ_zz = λ (ε_xx + ε_yy).
    """
    basis = point_basis(body) if basis is None else basis
    grad = basis.interpolate(body.full(u_nodes)).grad  # (2, 2, E, P): du_i/dx_j
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
    (at some meshes an x row of a node then misses a column its y row has), and the
    interface rotation's in-place path needs a node's unknowns to share their columns."""
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
        sxx, syy, sxy, _ = _stress_components(u.grad, young, poisson)
        g = v.grad
        return sxx * g[0, 0] + syy * g[1, 1] + sxy * (g[0, 1] + g[1, 0])

    return form


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
        work = s[0] * gi[0, 0] + s[1] * gi[1, 1] + s[2] * (gi[0, 1] + gi[1, 0])
        out[i] = np.sum((work + density * g * np.asarray(phi)[1]) * dx, axis=1)
    return out, basis.element_dofs

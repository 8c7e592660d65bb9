"""Plane-strain linear elasticity of both bodies with scikit-fem (P1 triangles).

Each body is assembled on its own mesh; the two meet only through the contact
operator ``B`` (built in :mod:`solver.contact`). Essential conditions are
removed from the unknowns ("free" DOFs), so every matrix here is already
condensed.
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import scipy.sparse as sp
from skfem import Basis, ElementTriP1, ElementVector, FacetBasis, LinearForm, MeshTri, asm
from skfem.models.elasticity import lame_parameters, linear_elasticity

from .mesh import BodyMesh, TunnelMesh
from .spec import CaseSpec, Material


@dataclass(frozen=True)
class BodySystem:
    """The condensed elastic system of one body.

    Attributes
    ----------
    K : (n, n) CSR stiffness on the free DOFs (N/m per m of tunnel).
    f : (n,) consistent nodal loads on the free DOFs (N/m).
    free_of : (2, N) free-DOF index of component c at node j, -1 where constrained.
    """

    K: sp.csr_matrix
    f: np.ndarray
    free_of: np.ndarray

    @property
    def n(self) -> int:
        return self.f.size

    def expand(self, u_free: np.ndarray) -> np.ndarray:
        """Nodal displacements (2, N) from free-DOF values (constrained DOFs are 0)."""
        u = np.zeros(self.free_of.shape)
        mask = self.free_of >= 0
        u[mask] = u_free[self.free_of[mask]]
        return u

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


@dataclass(frozen=True)
class System:
    ground: BodySystem
    lining: BodySystem


def _basis(mesh: BodyMesh) -> Basis:
    return Basis(MeshTri(np.ascontiguousarray(mesh.p), np.ascontiguousarray(mesh.t)), ElementVector(ElementTriP1()))


def _near(values: np.ndarray, target: float, scale: float) -> np.ndarray:
    return np.abs(values - target) <= 1e-9 * scale


def _gravity(density: float, g: float) -> LinearForm:
    @LinearForm
    def load(v, w):
        return -density * g * v[1]

    return load


def _condense(basis: Basis, K, f, fixed: list[np.ndarray]) -> BodySystem:
    n_total = basis.N
    is_fixed = np.zeros(n_total, bool)
    for dofs in fixed:
        is_fixed[dofs] = True
    free = np.flatnonzero(~is_fixed)
    index = -np.ones(n_total, np.int64)
    index[free] = np.arange(free.size)
    K = K.tocsr()[free][:, free].tocsr()
    return BodySystem(K=K, f=np.asarray(f)[free], free_of=index[basis.nodal_dofs])


def _stiffness(basis: Basis, mat: Material):
    return asm(linear_elasticity(*lame_parameters(mat.young, mat.poisson)), basis)


def assemble_system(spec: CaseSpec, mesh: TunnelMesh) -> System:
    """Stiffness and loads of ground and lining, condensed on the essential conditions."""
    return System(ground=_assemble_ground(spec, mesh.ground), lining=_assemble_lining(spec, mesh.lining))


def _assemble_ground(spec: CaseSpec, body: BodyMesh) -> BodySystem:
    geo, loads, bc = spec.geometry, spec.loads, spec.boundaries
    basis = _basis(body)
    mesh = basis.mesh
    scale = max(geo.width, geo.height)
    K = _stiffness(basis, spec.ground)
    f = asm(_gravity(spec.ground.density, loads.gravity), basis)

    q = loads.surface_load
    top = FacetBasis(mesh, basis.elem, facets=mesh.facets_satisfying(lambda x: _near(x[1], 0.0, scale)))

    @LinearForm
    def surface(v, w):
        return -q * v[1]

    f = f + asm(surface, top)

    x, y = mesh.p
    dofs = basis.nodal_dofs
    fixed = [dofs[0, _near(x, 0.0, scale)]]
    bottom = _near(y, -geo.height, scale)
    fixed.append(dofs[:, bottom].ravel() if bc.bottom == "fixed" else dofs[1, bottom])
    side = _near(x, geo.width, scale)
    if bc.side == "fixed":
        fixed.append(dofs[:, side].ravel())
    elif bc.side == "roller":
        fixed.append(dofs[0, side])
    else:
        right = FacetBasis(mesh, basis.elem,
                           facets=mesh.facets_satisfying(lambda x: _near(x[0], geo.width, scale)))
        k0, rho_g = loads.lateral_ratio, spec.ground.density * loads.gravity

        @LinearForm
        def side_pressure(v, w):
            return -k0 * (q - rho_g * w.x[1]) * v[0]

        f = f + asm(side_pressure, right)
    return _condense(basis, K, f, fixed)


def _assemble_lining(spec: CaseSpec, body: BodyMesh) -> BodySystem:
    basis = _basis(body)
    K = _stiffness(basis, spec.lining)
    f = asm(_gravity(spec.lining.density, spec.loads.gravity), basis)
    on_axis = _near(basis.mesh.p[0], 0.0, spec.geometry.outer_radius)
    return _condense(basis, K, f, [basis.nodal_dofs[0, on_axis]])


def element_stress(mesh: BodyMesh, mat: Material, u: np.ndarray) -> np.ndarray:
    """Constant P1 stresses per triangle, (4, E): xx, yy, xy, zz in Pa (tension positive).

    ``u`` is the nodal displacement (2, N); plane strain gives
    sigma_zz = lambda (eps_xx + eps_yy).
    """
    p, t = mesh.p, mesh.t
    grads, _ = p1_gradients(mesh)
    ue = u[:, t]  # (2, 3, E)
    eps_xx = np.einsum("ke,ke->e", grads[0], ue[0])
    eps_yy = np.einsum("ke,ke->e", grads[1], ue[1])
    eps_xy = 0.5 * (np.einsum("ke,ke->e", grads[1], ue[0]) + np.einsum("ke,ke->e", grads[0], ue[1]))
    lam, mu = lame_parameters(mat.young, mat.poisson)
    tr = eps_xx + eps_yy
    return np.stack([lam * tr + 2 * mu * eps_xx, lam * tr + 2 * mu * eps_yy, 2 * mu * eps_xy, lam * tr])


def p1_gradients(mesh: BodyMesh) -> tuple[np.ndarray, np.ndarray]:
    """Gradients of the three P1 shape functions, (2, 3, E) in 1/m, and areas (E,) in m^2."""
    p, t = mesh.p, mesh.t
    x, y = p[0, t], p[1, t]  # (3, E)
    det = (x[1] - x[0]) * (y[2] - y[0]) - (x[2] - x[0]) * (y[1] - y[0])
    gx = np.stack([y[1] - y[2], y[2] - y[0], y[0] - y[1]]) / det
    gy = np.stack([x[2] - x[1], x[0] - x[2], x[1] - x[0]]) / det
    return np.stack([gx, gy]), 0.5 * det

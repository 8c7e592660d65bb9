"""The consistent tangent of the Mohr–Coulomb return (:func:`solver.mohr_coulomb.return_stress`), for a
Newton iteration of the plastic equilibrium.

The surfaces are planes in principal space, so the return is piecewise linear in the trial's principal
stresses: on each piece the active surfaces (those the returned stress lies on) fix the principal
Jacobian ``J = I - D B (Nᵀ D B)⁻¹ Nᵀ`` (zero at a corner: three or more surfaces), and
:func:`solver.ground.tangent.full_tangent` adds the spin of the in-plane principal directions. The active set
is read off the returned stress (within :data:`ACTIVE_TOL` of a surface): on the boundary between two
pieces the return is not differentiable and either one-sided tangent is given.
"""
from __future__ import annotations

import numpy as np

from .mohr_coulomb import Material, principal, return_stress, yield_values
from .tangent import active_set_jacobian, elastic_matrix, full_tangent, unsort

#: A surface is active where the returned stress lies within this (relative) distance of it.
ACTIVE_TOL = 1e-8


def _planes(sin_phi: np.ndarray, sin_psi: np.ndarray):
    """Normals and flow directions (m, 6, 3) of the main plane (1, 3), the edges (2, 3), (1, 2) and the
    cut-offs of σ1, σ2, σ3, in sorted principal axes (the order of ``yield_values``' rows)."""
    m = sin_phi.size
    A, B = np.zeros((m, 6, 3)), np.zeros((m, 6, 3))
    for k, (i, j) in enumerate(((0, 2), (1, 2), (0, 1))):
        A[:, k, i], A[:, k, j] = 1.0 + sin_phi, -(1.0 - sin_phi)
        B[:, k, i], B[:, k, j] = 1.0 + sin_psi, -(1.0 - sin_psi)
    for k in range(3):
        A[:, 3 + k, k] = B[:, 3 + k, k] = 1.0
    return A, B


def consistent_tangent(trial: np.ndarray, mat: Material, flag_tolerance: float | None = None):
    """The Mohr–Coulomb return (as :func:`solver.mohr_coulomb.return_stress`) of trial stresses (4, n) and
    its algorithmic tangent (n, 4, 4): strain increments (dεxx, dεyy, dγxy, dεzz), engineering shear
    γxy = 2 εxy, to stress increments (dσxx, dσyy, dσxy, dσzz); the elastic matrix at points inside.

    Returns ``(stress, plastic_strain, at_yield, tangent)``.
    """
    args = () if flag_tolerance is None else (flag_tolerance,)
    stress, dep, at_yield = return_stress(trial, mat, *args)
    tangent = elastic_matrix(mat.lam, mat.mu)
    todo = np.flatnonzero(np.any(dep != 0.0, axis=0))
    if todo.size == 0:
        return stress, dep, at_yield, tangent
    m = mat.at(todo)
    tr, st = trial[:, todo], stress[:, todo]
    major, minor, angle, szz = principal(tr)
    vals = np.stack([major, minor, szz])
    order = np.argsort(-vals, axis=0, kind="stable")
    # the returned stress in the trial's principal axes (the return keeps them), sorted as the trial
    c, s = np.cos(angle), np.sin(angle)
    sa = st[0] * c * c + st[1] * s * s + 2.0 * st[2] * s * c
    sb = st[0] * s * s + st[1] * c * c - 2.0 * st[2] * s * c
    ret = np.take_along_axis(np.stack([sa, sb, st[3]]), order, axis=0)  # (3, k)
    scale = np.maximum(np.maximum(np.abs(vals).max(axis=0), m.c), 1.0)
    # the three Mohr–Coulomb planes (the main one's function on each pair) and the cut-offs
    fv = np.vstack([yield_values(ret[[i, i, j]], m.c, m.sin_phi, m.cos_phi, m.tensile)[0]
                    for i, j in ((0, 2), (1, 2), (0, 1))] + [ret - m.tensile])
    active = fv >= -ACTIVE_TOL * scale[None, :]  # (6, k)
    A, B = _planes(m.sin_phi, m.sin_psi)
    J = np.zeros((todo.size, 3, 3))
    codes = np.packbits(active.T, axis=1, bitorder="little")[:, 0]
    for code in np.unique(codes):
        p = np.flatnonzero(codes == code)
        rows = np.flatnonzero(active[:, p[0]])
        J[p] = active_set_jacobian(A[p][:, rows], B[p][:, rows], m.lam[p], m.mu[p])
    tangent[todo] = full_tangent(tr, st, unsort(J, order), m.lam, m.mu, scale)
    return stress, dep, at_yield, tangent

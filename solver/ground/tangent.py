"""The algorithmic (consistent) tangent of an isotropic return mapping in principal space, in the
plane-strain layout the FE uses.

A return that keeps the in-plane principal directions of the trial stress is a function of the
trial's principal values; with its principal Jacobian ``J = ∂σ_p/∂τ_p`` (3×3, axes (major in-plane,
minor in-plane, zz)) the derivative in components adds the *spin* of the in-plane directions:
a rotation dθ of the trial's axes rotates the returned stress by as much, which weighs the shear
direction by ``(σa - σb)/(τa - τb)``. The tangent maps strain increments
``(dεxx, dεyy, dγxy, dεzz)`` (engineering shear strain γxy = 2 εxy) to stress increments
``(dσxx, dσyy, dσxy, dσzz)``: ``C = (∂σ/∂τ) D`` with ``D`` the elastic matrix in that layout.

For an active set of surfaces with normals ``n_j`` (at the returned stress) and flow directions
``b_j``, the returned stress ``σ = τ - D_p Σ Δγ_l b_l`` with ``n_j · dσ = 0`` gives
``J = I - D_p B (Nᵀ D_p B)⁻¹ Nᵀ`` (:func:`active_set_jacobian`).
"""
from __future__ import annotations

import numpy as np

from .principal import principal


def elastic_matrix(lam, mu) -> np.ndarray:
    """Isotropic elasticity (n, 4, 4): (εxx, εyy, γxy, εzz) → (σxx, σyy, σxy, σzz); ``lam``, ``mu``
    (Pa) of shape (n,)."""
    lam, mu = np.atleast_1d(np.asarray(lam, float)), np.atleast_1d(np.asarray(mu, float))
    D = np.zeros((lam.size, 4, 4))
    for i in (0, 1, 3):
        for j in (0, 1, 3):
            D[:, i, j] = lam
        D[:, i, i] += 2.0 * mu
    D[:, 2, 2] = mu
    return D


def principal_elasticity(lam, mu) -> np.ndarray:
    """Isotropic elasticity in principal axes (n, 3, 3): λ 1 1ᵀ + 2μ I."""
    lam, mu = np.atleast_1d(np.asarray(lam, float)), np.atleast_1d(np.asarray(mu, float))
    return lam[:, None, None] * np.ones((1, 3, 3)) + 2.0 * mu[:, None, None] * np.eye(3)


def active_set_jacobian(normals: np.ndarray, flows: np.ndarray, lam, mu) -> np.ndarray:
    """``J = I - D B (Nᵀ D B)⁻¹ Nᵀ`` (m, 3, 3) of returns onto ``k`` active surfaces with normals
    ``normals`` and flow directions ``flows`` (m, k, 3); ``k = 0`` gives the identity. Where the
    normals span principal space (a corner point) the returned stress is fixed: J = 0."""
    m, k = normals.shape[:2]
    J = np.broadcast_to(np.eye(3), (m, 3, 3)).copy()
    if k == 0:
        return J
    Dp = principal_elasticity(lam, mu)
    DB = np.einsum("pxy,pky->pxk", Dp, flows)  # (m, 3, k)
    M = np.einsum("pjx,pxk->pjk", normals, DB)  # (m, k, k)
    if k >= 3:
        return np.zeros((m, 3, 3))  # k independent normals, k ≥ 3: a point of principal space
    return J - DB @ np.linalg.solve(M, normals)


def unsort(J: np.ndarray, order: np.ndarray) -> np.ndarray:
    """A principal Jacobian (m, 3, 3) in sorted axes (σ1 ≥ σ2 ≥ σ3) back to the trial's axes, where
    ``order`` (3, m) lists, per point, the trial's axis of each sorted one: J_axes[o_i, o_j] = J[i, j]."""
    out = np.empty_like(J)
    idx = order.T
    out[np.arange(J.shape[0])[:, None, None], idx[:, :, None], idx[:, None, :]] = J
    return out


def full_tangent(trial: np.ndarray, stress: np.ndarray, J: np.ndarray, lam, mu,
                 scale: np.ndarray | None = None) -> np.ndarray:
    """The consistent tangent (m, 4, 4) (layout in the module's docstring) of a return with
    principal Jacobian ``J`` (m, 3, 3) in the axes (major in-plane, minor in-plane, zz) of the trial
    (4, m), whose returned stress (4, m) has the trial's in-plane directions."""
    ta, tb, (c2, s2), _ = principal(trial)
    sa, sb, _, _ = principal(stress)
    m = trial.shape[1]
    # d(τa, τb, τzz) and r d(2θ) as rows acting on dτ = (xx, yy, xy, zz)
    T = np.zeros((m, 4, 4))
    T[:, 0, :] = np.stack([0.5 + 0.5 * c2, 0.5 - 0.5 * c2, s2, np.zeros(m)], axis=1)
    T[:, 1, :] = np.stack([0.5 - 0.5 * c2, 0.5 + 0.5 * c2, -s2, np.zeros(m)], axis=1)
    T[:, 2, 3] = 1.0
    T[:, 3, :] = np.stack([-0.5 * s2, 0.5 * s2, c2, np.zeros(m)], axis=1)
    gap = ta - tb
    if scale is None:
        scale = np.maximum(np.abs(trial).max(axis=0), 1.0)
    with np.errstate(all="ignore"):
        spin = np.where(np.abs(gap) > 1e-9 * scale, (sa - sb) / gap, J[:, 0, 0] - J[:, 0, 1])
    # σ = ½(σa + σb)(1, 1, 0, 0) + ½(σa - σb) u + σzz e4 with u = (cos 2θ, -cos 2θ, sin 2θ, 0);
    # dσ = ... + ½(σa - σb) w d(2θ), w = (-sin 2θ, sin 2θ, cos 2θ, 0)
    u = np.stack([c2, -c2, s2, np.zeros(m)], axis=1)
    w = np.stack([-s2, s2, c2, np.zeros(m)], axis=1)
    mean = np.zeros((m, 4))
    mean[:, :2] = 0.5
    e4 = np.zeros((m, 4))
    e4[:, 3] = 1.0
    # rows of d(σa, σb, σzz) on dτ
    dP = np.einsum("pij,pjk->pik", J, T[:, :3, :])
    dS = (mean[:, :, None] * (dP[:, 0, None, :] + dP[:, 1, None, :])
          + 0.5 * u[:, :, None] * (dP[:, 0, None, :] - dP[:, 1, None, :])
          + e4[:, :, None] * dP[:, 2, None, :]
          + spin[:, None, None] * w[:, :, None] * T[:, 3, None, :])
    return dS @ elastic_matrix(lam, mu)

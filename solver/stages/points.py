"""The yielding ground's stress history at one set of points, and what the plastic solve needs
of it: the stress of a displacement, the plastic load and its tangent (SPEC §1.5).

With ``ε_p`` the plastic strain, the ground's equilibrium ``∫Bᵀ(σ - σ0′) = f`` reads
``K u = f + p(u)`` with the plastic load ``p = ∫Bᵀ τ``, ``τ = σ0′ + D ε(u) - σ(u)`` (= D ε_p),
non-zero only where the ground yields. Its derivative ``P′ = ∫Bᵀ (D - C) B`` (``C`` the laws'
algorithmic tangent) is non-zero only at the points the last return moved: the equilibrium's
tangent stiffness is ``K - P′``. Strains come from one sparse gradient operator per set of points
(:meth:`~solver.model.TunnelModel.gradient_operator`), whose transpose integrates. The laws are
callables (:mod:`solver.ground.laws`); nothing here knows which.
"""
from __future__ import annotations

from typing import NamedTuple

import numpy as np

from ..ground.laws import ground_laws
from ..ground.loads import in_situ_stress, moduli
from ..ground.mohr_coulomb import equivalent
from ..ground.strata import strata
from ..ground.tangent import elastic_matrix


class State(NamedTuple):
    """One displacement's state: the free-DOF displacement, its gradient (2, 2, E, Q), stress,
    plastic strain increment (3, E·Q), yield flags (E, Q), ``τ`` (4, E, Q) and the returned
    points with ``D - C`` there ((r,), (r, 4, 4); None without the tangent)."""

    u: np.ndarray
    grad: np.ndarray
    stress: np.ndarray
    dep: np.ndarray
    flags: np.ndarray
    tau: np.ndarray
    returned: np.ndarray | None
    softening: np.ndarray | None


class Points:
    """The ground's stress history at one set of points (quadrature or output points)."""

    def __init__(self, model, spec, where: str):
        basis = model.ground.body.basis if where == "gauss" else model.point_basis("ground")
        self.G = model.gradient_operator(where)
        self.weights = basis.dx
        layers = strata(spec)
        y = np.asarray(basis.global_coordinates())[1]  # (E, Q)
        self.shape = y.shape
        young, poisson = moduli(layers, model.band, y)  # the case's (the model's may differ by a scale)
        young, poisson = np.broadcast_to(young, y.shape), np.broadcast_to(poisson, y.shape)
        lam = young * poisson / ((1 + poisson) * (1 - 2 * poisson))
        mu = young / (2 * (1 + poisson))
        self.lam, self.mu, self.mu2 = lam, mu, 2 * mu
        self.laws = ground_laws(layers, model.band, lam, mu)
        self.sigma0 = (in_situ_stress(spec, layers, model.band, y)["effective"]  # (4, E, Q)
                       if spec.excavation.method == "deconfinement" else np.zeros((4,) + y.shape))
        self.sigma = self.sigma0.copy()  # at the last converged increment
        self.grad = np.zeros((2, 2) + y.shape)
        self.tau = np.zeros((4,) + y.shape)  # σ0′ + D ε - σ = D ε_p
        self.eqps = np.zeros(y.shape)
        self.at_yield = np.zeros(y.shape, bool)
        #: the elements that have had a plastic strain so far, their points and those points'
        #: rows of ``G``, transposed (:meth:`plastic_load`)
        self.yielded = (np.zeros(y.shape[0], bool), None, None)

    @property
    def yielding(self) -> bool:
        return bool(self.laws)

    def hooke(self, grad: np.ndarray, onto: np.ndarray | None = None) -> np.ndarray:
        """The elastic stress (4, E, Q) of a displacement gradient (2, 2, E, Q), plane strain;
        added to a copy of ``onto`` (4, E, Q) if given (the trial of every iterate)."""
        out = np.zeros((4,) + grad.shape[2:]) if onto is None else onto.copy()
        lt = grad[0, 0] + grad[1, 1]
        lt *= self.lam
        out[3] += lt
        out[0] += lt
        out[1] += lt
        out[0] += self.mu2 * grad[0, 0]
        out[1] += self.mu2 * grad[1, 1]
        shear = grad[0, 1] + grad[1, 0]
        shear *= self.mu
        out[2] += shear
        return out

    def gradient(self, u_free: np.ndarray) -> np.ndarray:
        """The displacement gradient (2, 2, E, Q) of the ground's unknowns ``u_free``."""
        return (self.G @ u_free).reshape((2, 2) + self.shape)

    def state(self, u_free: np.ndarray, tangent: bool = False, frozen: np.ndarray | None = None) -> State:
        """The state of a displacement since excavation, returned from the last converged
        increment; with ``tangent``, ``D - C`` at the returned points; ``frozen`` (E·Q,) bool
        fixes which points flow (:mod:`solver.ground.laws`)."""
        grad = self.gradient(u_free)
        trial = self.hooke(grad - self.grad, onto=self.sigma)
        flat = trial.reshape(4, -1)
        stress = flat.copy()
        dep = np.zeros((3, flat.shape[1]))
        flags = np.zeros(flat.shape[1], bool)
        returned, soft = [], []
        for at, law in self.laws:
            stress[:, at], dep[:, at], flags[at], r, C = law(flat[:, at], tangent,
                                                              None if frozen is None else frozen[at])
            if tangent and r.size:
                returned.append(at[r])
                soft.append(elastic_matrix(self.lam.ravel()[at[r]], self.mu.ravel()[at[r]]) - C)
        stress = stress.reshape(trial.shape)
        if tangent:
            returned = np.concatenate(returned) if returned else np.zeros(0, np.int64)
            soft = np.concatenate(soft) if soft else np.zeros((0, 4, 4))
        else:
            returned = soft = None
        return State(u_free, grad, stress, dep, flags.reshape(self.shape), self.tau + (trial - stress),
                     returned, soft)

    def flowing(self, state: State) -> np.ndarray:
        """(E·Q,) bool: the points ``state`` returned (it must have its tangent)."""
        mask = np.zeros(self.shape[0] * self.shape[1], bool)
        mask[state.returned] = True
        return mask

    def commit(self, state: State) -> None:
        """Make ``state`` the last converged one."""
        self.grad, self.sigma, self.tau = state.grad, state.stress, state.tau
        self.eqps = self.eqps + equivalent(state.dep).reshape(self.shape)
        self.at_yield = state.flags

    def plastic_load(self, tau: np.ndarray) -> np.ndarray:
        """``∫Bᵀ τ`` on the ground's unknowns from ``tau`` (4, E, Q): non-zero only where the
        ground has yielded, so only the rows of the gradient operator at the points of the
        elements that have yielded so far are used (:attr:`yielded`, grown when others yield)."""
        elements, at, GT = self.yielded
        now = (tau.reshape(4, -1) != 0).any(axis=0).reshape(self.shape).any(axis=1)  # (E,)
        if (now & ~elements).any():
            elements = elements | now
            E, Q = self.shape
            at = (np.flatnonzero(elements)[:, None] * Q + np.arange(Q)).ravel()  # their points
            GT = self.G[(np.arange(4)[:, None] * (E * Q) + at[None, :]).ravel()].T.tocsr()
            self.yielded = elements, at, GT
        if GT is None:
            return np.zeros(self.G.shape[1])
        w = self.weights.reshape(-1)[at]
        t = tau.reshape(4, -1)[:, at]
        return GT @ np.concatenate([t[0] * w, t[2] * w, t[2] * w, t[1] * w])

    def softening(self, state: State):
        """The plastic load's derivative ``v ↦ P′ v = ∫Bᵀ (D - C) ε(v)`` at ``state`` (which has
        its tangent): a function of ground displacements, zero where no point returned."""
        at = state.returned
        n = self.G.shape[1]
        if at.size == 0:
            return lambda v: np.zeros(n)
        EQ = self.shape[0] * self.shape[1]
        Gp = self.G[(np.arange(4)[:, None] * EQ + at[None, :]).ravel()].tocsr()
        GpT = Gp.T.tocsr()
        w = self.weights.reshape(-1)[at]
        M = state.softening * w[:, None, None]  # (r, 4, 4), weighted

        def apply(v: np.ndarray) -> np.ndarray:
            g = (Gp @ v).reshape(4, -1)
            strain = np.stack([g[0], g[3], g[1] + g[2], np.zeros_like(g[0])], axis=1)  # (r, 4)
            t = np.einsum("pij,pj->ip", M, strain)
            return GpT @ np.concatenate([t[0], t[2], t[2], t[1]])

        return apply


def first_yield(points: Points, u_unit: np.ndarray, limit: float) -> float:
    """The largest fraction ``f`` ≤ ``limit`` of the displacement ``u_unit`` (added to the last
    converged state) for which every point's stress stays inside its yield surface. The stress
    is linear in ``f`` and the yield function convex in the stress, so each point's admissible
    fractions are an interval ``[0, f_i]``: the bisection (to 1e-4 of ``limit``, from below)
    runs only if some point is outside at ``limit``."""
    rate = points.hooke(points.gradient(u_unit)).reshape(4, -1)
    start = points.sigma.reshape(4, -1)
    best = limit
    for at, law in points.laws:
        def outside(f: float) -> bool:
            return bool(law(start[:, at] + f * rate[:, at], False)[2].any())

        if not outside(best):
            continue
        low, high = 0.0, best
        while high - low > 1e-4 * limit:
            mid = 0.5 * (low + high)
            low, high = (low, mid) if outside(mid) else (mid, high)
        best = low
    return best

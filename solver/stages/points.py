"""The ground's stress history at a set of points (quadrature points or the stored faces' points) and what
it answers: the state at a displacement (:meth:`Points.state`: trial stress, return, plastic strain), the
plastic load it makes (:func:`plastic_load`) and how far a stage's displacement takes it before any point
yields (:func:`elastic_increments`).
"""
from __future__ import annotations

import copy

import numpy as np
from numba import njit

from ..ground.laws import PointLaws
from ..ground.loads import in_situ_stress, moduli
from ..ground.mohr_coulomb import equivalent
from ..ground.strata import strata

#: The least distance from the yield surface (relative) at which a point is reported at yield:
#: a tenth of ``solver.plastic_tolerance`` if coarser (the iteration leaves yielding points a hair inside).
FLAG_TOLERANCE = 1e-3


class Points:
    """The ground's stress history at one set of points (quadrature or output points)."""

    def __init__(self, model, spec, where: str):
        basis = model.ground.body.basis if where == "gauss" else model.point_basis("ground")
        self.basis = basis
        self.G = model.gradient_operator(where)
        self.weights = basis.dx
        layers = strata(spec)
        self.layers = layers
        band = model.band
        y = np.asarray(basis.global_coordinates())[1]  # (E, Q)
        self.shape = y.shape
        young, poisson = moduli(layers, band, y)  # the case's (the model's may differ by a scale)
        young = np.broadcast_to(young, y.shape)
        poisson = np.broadcast_to(poisson, y.shape)
        lam = young * poisson / ((1 + poisson) * (1 - 2 * poisson))
        mu = young / (2 * (1 + poisson))
        self.lam, self.mu = lam, mu
        per = lambda name: np.broadcast_to(  # noqa: E731
            np.array([getattr(s, name) for s in layers])[band][:, None], y.shape).ravel()
        law = np.broadcast_to(np.array([s.model for s in layers])[band][:, None], y.shape).ravel()
        self.yielding = law != "elastic"
        sel = self.yielding
        self.material = PointLaws.of(law[sel], lam.ravel()[sel], mu.ravel()[sel], lambda k: per(k)[sel])
        self.sigma0 = (in_situ_stress(spec, layers, band, y)["effective"]  # (4, E, Q)
                       if spec.excavation.method == "deconfinement" else np.zeros((4,) + y.shape))
        self.sigma = self.sigma0.copy()  # at the last converged increment
        self.grad = np.zeros((2, 2) + y.shape)
        self.tau = np.zeros((4,) + y.shape)  # σ0′ + D ε - σ = D ε_p
        self.eqps = np.zeros(y.shape)
        self.at_yield = np.zeros(y.shape, bool)
        #: the elements that have had a plastic strain so far, their points and those points'
        #: rows of ``G``, transposed (:func:`plastic_load`)
        self.yielded = (np.zeros(y.shape[0], bool), None, None)
        #: a point within this (relative) distance of the yield surface counts as at yield: the
        #: equilibrium iteration's tolerance leaves yielding points a hair inside it
        self.flag_tolerance = max(spec.solver.plastic_tolerance / 10, FLAG_TOLERANCE)
        self._part = None  # the last elements :meth:`follow` followed, and their :meth:`part`

    def hooke(self, grad: np.ndarray, onto: np.ndarray | None = None, since: np.ndarray | None = None) -> np.ndarray:
        """The elastic stress (4, E, Q) of a displacement gradient (2, 2, E, Q) (less ``since``, if given),
        plane strain; added to ``onto`` (4, E, Q) if given: the trial of every iterate, in one compiled pass."""
        none = np.zeros((4, 0))
        flat = lambda a: none if a is None else np.ascontiguousarray(a).reshape(4, -1)  # noqa: E731
        out = np.empty((4,) + grad.shape[2:])
        _hooke(flat(grad), flat(since), flat(onto), np.ascontiguousarray(self.lam).reshape(-1),
               np.ascontiguousarray(self.mu).reshape(-1), out.reshape(4, -1))
        return out

    def gradient(self, u_free: np.ndarray) -> np.ndarray:
        """The displacement gradient (2, 2, E, Q) of the ground's unknowns ``u_free``."""
        return (self.G @ u_free).reshape((2, 2) + self.shape)

    def trial(self, grad: np.ndarray):
        """Stress, plastic strain increment, yield flags and ``D ε_p`` of a displacement
        gradient since excavation, from the last converged increment."""
        trial = self.hooke(grad, onto=self.sigma, since=self.grad)
        flat = trial.reshape(4, -1)
        dep = np.zeros((3, flat.shape[1]))
        flags = np.zeros(flat.shape[1], bool)
        sel = self.yielding
        if sel.all():
            stress, dep, flags = self.material.return_stress(flat, self.flag_tolerance)
        else:
            stress = flat.copy()
            if sel.any():
                stress[:, sel], dep[:, sel], flags[sel] = self.material.return_stress(flat[:, sel],
                                                                                     self.flag_tolerance)
        # (a point flowing in this increment is at yield: return_stress flags every point it returns)
        stress = stress.reshape(trial.shape)
        tau = np.empty_like(trial)
        _plastic_part(self.tau.reshape(4, -1), trial.reshape(4, -1), stress.reshape(4, -1), tau.reshape(4, -1))
        return stress, dep, flags.reshape(self.shape), tau

    def state(self, u_free: np.ndarray) -> tuple:
        """The state at the ground's unknowns ``u_free`` as the equilibrium iteration carries it:
        ``(u_free, grad, stress, plastic strain increment, flags, D ε_p)`` (:meth:`trial`)."""
        grad = self.gradient(u_free)
        return (u_free, grad) + self.trial(grad)

    #: what a converged increment leaves at the points (:meth:`commit`, :meth:`history`)
    HISTORY = ("grad", "sigma", "tau", "eqps", "at_yield", "yielded")

    def history(self) -> dict:
        """The points' history as it stands, read-only (:func:`_first_stage` keeps it on the model:
        every later commit replaces these arrays, none writes into them)."""
        kept = {name: getattr(self, name) for name in self.HISTORY}
        for value in kept.values():
            if isinstance(value, np.ndarray):
                value.flags.writeable = False
        return kept

    def restore(self, history: dict) -> None:
        self.__dict__.update(history)

    def commit(self, grad, stress, dep, flags, tau) -> None:
        self.grad, self.sigma, self.tau = grad, stress, tau
        self.eqps = self.eqps + equivalent(dep).reshape(self.shape)
        self.at_yield = flags

    def of(self, at: np.ndarray) -> np.ndarray:
        """The points (their flat indices) of the elements ``at`` (indices), in their order."""
        Q = self.shape[1]
        return (at[:, None] * Q + np.arange(Q)).ravel()

    def rows(self, at: np.ndarray) -> np.ndarray:
        """The rows of the gradient operator at the points of the elements ``at`` (indices), in their order."""
        E, Q = self.shape
        return (np.arange(4)[:, None] * (E * Q) + self.of(at)[None, :]).ravel()

    def has_yielded(self) -> np.ndarray:
        """The elements (E,) with a point at yield (within the flag tolerance) or with a plastic strain."""
        return self.at_yield.any(axis=1) | (self.eqps > 0).any(axis=1)

    def part(self, at: np.ndarray, G) -> "Points":
        """The points of the elements ``at`` (indices) as points of their own, ``G`` their rows of the gradient
        operator (on whatever unknowns the caller reads them): what no commit changes; :meth:`as_committed`
        gives them their history."""
        sub = copy.copy(self)
        points = self.of(at)
        sub.G, sub.shape = G, (at.size, self.shape[1])
        sub.yielding = self.yielding[points]
        sub.material = self.material.at((np.cumsum(self.yielding) - 1)[points][sub.yielding])
        for name in ("lam", "mu", "weights"):
            setattr(sub, name, getattr(self, name)[at])
        return sub

    def as_committed(self, part: "Points", at: np.ndarray) -> "Points":
        """A copy of ``part`` (:meth:`part` of the elements ``at``) with their history as committed."""
        sub = copy.copy(part)
        sub.eqps, sub.at_yield = self.eqps[at], self.at_yield[at]
        sub.sigma, sub.tau, sub.grad = self.sigma[:, at], self.tau[:, at], self.grad[:, :, at]
        sub.yielded = (np.zeros(at.size, bool), None, None)
        return sub

    def follow(self, u_free: np.ndarray, elements: np.ndarray | None = None) -> None:
        """Commit the state at the ground's unknowns ``u_free`` at the points of ``elements`` ((E,) mask; all if
        None), the others' history left as it stands: exact where they are elastic now and were at every commit
        they missed (their stress is then their trial from any of those states: :func:`follows`)."""
        if elements is None or elements.all():
            grad = self.gradient(u_free)
            self.commit(grad, *self.trial(grad))
            return
        at = np.flatnonzero(elements)
        if at.size == 0:  # (nothing can yield yet: no history changes)
            return
        if self._part is None or not np.array_equal(self._part[0], at):
            self._part = (at, self.part(at, self.G[self.rows(at)]))
        sub = self.as_committed(self._part[1], at)
        grad = sub.gradient(u_free)
        stress, dep, flags, tau = sub.trial(grad)
        for name in ("grad", "sigma", "tau", "eqps", "at_yield"):  # (kept histories are read-only: copied once)
            if not getattr(self, name).flags.writeable:
                setattr(self, name, getattr(self, name).copy())
        self.grad[:, :, at], self.sigma[:, at], self.tau[:, at], self.at_yield[at] = grad, stress, tau, flags
        self.eqps[at] += equivalent(dep).reshape(sub.shape)


def affine_elements(model) -> np.ndarray:
    """The ground's triangles (E,) whose map is affine (straight-sided: its Jacobian the same at every
    quadrature point; the curved ones border the excavation), found once per model."""
    def find():
        basis = model.ground.body.basis
        detJ = basis.dx / basis.quadrature[1][None, :]
        return np.abs(detJ - detJ[:, :1]).max(axis=1) <= 1e-9 * np.abs(detJ[:, :1]).ravel()
    return model.built(("affine elements",), find)


def follows(gauss: Points, out: Points, affine: np.ndarray) -> np.ndarray:
    """The elements (E,) whose ``out`` points a commit must follow: those with a ``gauss`` point at yield (within
    the flag tolerance) or that has yielded, with an ``out`` point that has, and those whose map is not ``affine``.
    In the others the stress has been elastic throughout, so it is affine on a straight triangle (the in-situ
    stress linear in depth within a layer, the strain linear for P2), the ``out`` points (sub-triangle centroids)
    lie in the convex hull of the quadrature points, and the yield function being convex, they are inside the
    surface where every quadrature point is."""
    return gauss.has_yielded() | out.has_yielded() | ~affine


def plastic_load(points: Points, tau: np.ndarray) -> np.ndarray:
    """``∫Bᵀ(σ0′ + D ε(u) - σ)`` on the ground's unknowns, at the quadrature points of
    ``points``, from ``tau`` = the bracket (4, E, Q): non-zero only where the ground has yielded,
    so only the rows of the gradient operator at the points of the elements that have yielded
    so far are used (:attr:`Points.yielded`, grown when others yield)."""
    elements, at, GT = points.yielded
    now = (tau.reshape(4, -1) != 0).any(axis=0).reshape(points.shape).any(axis=1)  # (E,)
    if (now & ~elements).any():
        elements = elements | now
        which = np.flatnonzero(elements)
        at, GT = points.of(which), points.G[points.rows(which)].T  # their points and rows
        points.yielded = elements, at, GT
    if GT is None:
        return np.zeros(points.G.shape[1])
    w = points.weights.reshape(-1)[at]
    t = tau.reshape(4, -1)[:, at]
    return GT @ np.concatenate([t[0] * w, t[2] * w, t[2] * w, t[1] * w])


def _yield_along(points: Points, u_unit: np.ndarray):
    """``at_yield(f, where, material)``: the yield flags of the yielding points ``where`` (their law
    ``material``) at the fraction ``f`` of the displacement ``u_unit`` added to the last converged state."""
    rate = points.hooke(points.gradient(u_unit)).reshape(4, -1)[:, points.yielding]
    start = points.sigma.reshape(4, -1)[:, points.yielding]

    def at_yield(f: float, where, material) -> np.ndarray:
        return material.return_stress(start[:, where] + f * rate[:, where], points.flag_tolerance)[2]

    return at_yield


def elastic_increments(points: Points, u_stage: np.ndarray, steps: int) -> tuple[int, np.ndarray]:
    """How many of a stage's ``steps`` equal increments of the displacement ``u_stage`` (linear in the stage's
    load, added to the last converged state) the ``points`` take with none at yield (those the stage solves in
    one step), and the elements (E,) with a point at yield at the stage's end so (where the stage will yield,
    as the elastic ground sees it: a yielding zone's start, :mod:`solver.stages.region`). Each point's stress is
    linear in the fraction and its yield function convex in the stress, so its admissible fractions are an
    interval ``[0, f_i]``: a point inside at the stage's end is inside all the way, and the bisection over the
    increments' ends looks only at the points that are not (a few returns). Stage 1's increments below the
    first yield are one elastic solve; so are the contact stage's (:func:`solver.stages.plastic._elastic_contact`)."""
    at_end = np.zeros(points.shape, bool)
    if not points.yielding.any():
        return steps, at_end.any(axis=1)
    at_yield = _yield_along(points, u_stage)
    out = np.flatnonzero(at_yield(1.0, slice(None), points.material))
    at_end.reshape(-1)[np.flatnonzero(points.yielding)[out]] = True
    if out.size == 0:
        return steps, at_end.any(axis=1)
    material = points.material.at(out)
    low, high = 0, steps  # every point inside at low / steps, some at yield at high / steps
    while high - low > 1:
        mid = (low + high) // 2
        low, high = (low, mid) if at_yield(mid / steps, out, material).any() else (mid, high)
    return low, at_end.any(axis=1)


@njit(cache=True)
def _hooke(grad, since, onto, lam, mu, out):
    """``out`` (4, n) = ``onto`` + D (``grad`` - ``since``): plane-strain Hooke's law at n points, gradients (4, n)
    as (∂u/∂x, ∂u/∂y, ∂v/∂x, ∂v/∂y), stresses as (xx, yy, xy, zz); ``since`` or ``onto`` with no columns: zero."""
    minus, add = since.shape[1] > 0, onto.shape[1] > 0
    for i in range(out.shape[1]):
        g0, g1, g2, g3 = grad[0, i], grad[1, i], grad[2, i], grad[3, i]
        if minus:
            g0, g1, g2, g3 = g0 - since[0, i], g1 - since[1, i], g2 - since[2, i], g3 - since[3, i]
        lt = (g0 + g3) * lam[i]
        s0, s1, s2, s3 = (onto[0, i], onto[1, i], onto[2, i], onto[3, i]) if add else (0.0, 0.0, 0.0, 0.0)
        out[0, i] = (s0 + lt) + 2.0 * mu[i] * g0
        out[1, i] = (s1 + lt) + 2.0 * mu[i] * g3
        out[2, i] = s2 + (g1 + g2) * mu[i]
        out[3, i] = s3 + lt


@njit(cache=True)
def _plastic_part(tau, trial, stress, out):
    """``out`` = ``tau`` + (``trial`` - ``stress``), all (4, n): ``D ε_p`` since excavation after a return."""
    for x in range(4):
        for i in range(out.shape[1]):
            out[x, i] = tau[x, i] + (trial[x, i] - stress[x, i])

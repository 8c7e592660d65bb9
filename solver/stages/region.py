"""Stage 1's equilibrium iteration on the yielding zone alone (:func:`solver.stages.plastic._stage_one`).

The plastic load is non-zero only on the elements that have yielded, so the unsupported ground's
displacement is ``λ u_r + K⁻¹ p`` with ``p`` on their unknowns. Around them a zone of elements (those at
yield and :data:`LAYERS` rings around them) is kept; the rest of the ground is eliminated exactly (its
Schur complement, :class:`~solver.fe.condense.RegionSchur`), so each iteration computes strains, returns
stresses, mixes and solves on the zone's points and unknowns only: the same iterates as on the whole
ground (to rounding), at a fraction of the cost. What the zone assumes, that the ground outside it stays
elastic, is checked on the whole ground at each answer: where a point outside has reached yield, the zone
grows and the iteration goes on from there. The zone never shrinks within a stage; a zone of more than
:data:`MOST` of the ground's unknowns is given up for the whole ground's iteration (its factor would cost
as much). Zones are kept on the model (:data:`KEPT` of them): a sweep's cases whose ground yields alike
share them.
"""
from __future__ import annotations

import copy
from collections import OrderedDict

import numpy as np
import scipy.sparse as sp

from ..fe.condense import RegionSchur
from ..fe.linalg import nested_dissection
from .path import Stalled, fixed_point

#: Rings of elements kept around the elements at yield.
LAYERS = 2
#: A zone that grows takes this many times :data:`LAYERS` rings around the points at yield.
GROWTH = 2
#: A zone of more than this share of the ground's unknowns is given up (the whole ground's iteration).
MOST = 0.4
#: Zones (their factors) kept on a model.
KEPT = 3


class _Product:
    """``S @ x`` for :func:`~solver.stages.path.fixed_point` (its only use of the stiffness)."""

    def __init__(self, schur: RegionSchur, scale: float):
        self.schur, self.scale = schur, scale

    def __matmul__(self, x: np.ndarray) -> np.ndarray:
        return self.scale * self.schur.product(x)


def _adjacency(model) -> sp.csr_matrix:
    """Elements sharing a vertex (E, E), built once per model."""
    def build():
        t = model.ground.body.basis.mesh.t[:3]
        E = t.shape[1]
        inc = sp.csr_matrix((np.ones(t.size), (t.ravel(), np.tile(np.arange(E), 3))))
        return (inc.T @ inc).tocsr()
    return model.built(("element adjacency",), build)


def dilate(model, elements: np.ndarray, layers: int = LAYERS) -> np.ndarray:
    """The (E,) mask ``elements`` and ``layers`` rings of elements around it."""
    adj = _adjacency(model)
    out = elements.copy()
    for _ in range(layers):
        out = (adj @ out.astype(float)) > 0
    return out


class Zone:
    """The yielding zone of one stage-1 solve: the elements it covers, their points' history (from the
    whole ground's, ``gauss``: :class:`~solver.stages.plastic._Points`) and the ground condensed onto its
    unknowns. ``u_r`` is the ground's displacement under the whole excavation load."""

    def __init__(self, model, gauss, u_r: np.ndarray, elements: np.ndarray):
        self.model, self.gauss, self.u_r = model, gauss, u_r
        self.ground = model.ground
        self.elements = np.zeros(gauss.shape[0], bool)
        self.given_up = False
        self._grow(elements, GROWTH * LAYERS)

    @property
    def active(self) -> bool:
        return not self.given_up

    def _grow(self, elements: np.ndarray, layers: int = LAYERS) -> None:
        """Cover ``elements`` too (and ``layers`` rings around them)."""
        self.elements = self.elements | dilate(self.model, elements, layers)
        want = self.elements
        gauss = self.gauss
        E, Q = gauss.shape
        at = np.flatnonzero(want)
        points = (at[:, None] * Q + np.arange(Q)).ravel()
        rows = (np.arange(4)[:, None] * (E * Q) + points[None, :]).ravel()
        G = gauss.G[rows].tocsr()
        dofs = np.unique(G.indices)
        n = gauss.G.shape[1]
        if dofs.size == 0 or dofs.size > MOST * n:
            self.given_up = True
            return
        cache = self.model.built(("yielding zones",), OrderedDict)
        key = dofs.tobytes()
        schur = cache.get(key)
        if schur is None:
            body = self.ground.base.body
            order = self.model.built(("ground order",), lambda: nested_dissection(body.basis.mesh, body.node_of_dof()))
            inside = np.zeros(n, bool)
            inside[dofs] = True
            schur = RegionSchur(body.K, order, inside)
            cache[key] = schur
            while len(cache) > KEPT:
                cache.popitem(last=False)
        self.schur = schur
        self.scale = float(getattr(self.ground, "scale", 1.0))
        local = np.full(n, -1, np.int64)
        local[dofs] = np.arange(dofs.size)
        G = sp.csr_matrix((G.data, local[G.indices], G.indptr), shape=(G.shape[0], dofs.size))
        self._at, self._G = at, G
        self._u_r = self.u_r[dofs]
        self._g_r = self.scale * schur.product(self._u_r)  # the excavation load condensed onto the zone
        rank = np.cumsum(gauss.yielding) - 1
        self._yielding = gauss.yielding[points]
        self._material = gauss.material.at(rank[points][self._yielding])

    def points(self):
        """The zone's points as :class:`~solver.stages.plastic._Points` (their history as committed)."""
        g, at = self.gauss, self._at
        sub = copy.copy(g)
        sub.G, sub.shape = self._G, (at.size, g.shape[1])
        sub.yielding, sub.material = self._yielding, self._material
        for name in ("lam", "mu", "mu2", "weights", "eqps", "at_yield"):
            setattr(sub, name, getattr(g, name)[at])
        sub.sigma, sub.tau = g.sigma[:, at], g.tau[:, at]
        sub.grad = g.grad[:, :, at]
        sub.yielded = (np.zeros(at.size, bool), None, None)
        return sub

    def solve(self, plastic_load, rows, guess, limit: int, patience, atol: float, frac=None, arc=None):
        """:func:`~solver.stages.path.fixed_point` on the zone (stage 1's ``solve1``): the whole ground's
        displacement, plastic load and state at the answer, the iterations and the load. Before it, the zone
        grows to cover the points at yield as committed; after it, where a point outside the zone has
        reached yield, it grows and the iteration goes on."""
        g = self.gauss
        yielded = g.at_yield.any(axis=1) | (g.eqps > 0).any(axis=1)
        if self.active and (dilate(self.model, yielded) & ~self.elements).any():
            self._grow(yielded, GROWTH * LAYERS)  # grown by more than needed: each growth refactorizes
        used = 0
        ground = self.ground
        if arc is not None:
            x_s, normal, ds = arc
            w = ground.backward(ground.forward(normal, rows), rows)  # K⁻¹ n: n·K⁻¹p = (K⁻¹n)·p
            along, start = float(normal @ self.u_r), float(normal @ x_s)
        while self.active:
            if used >= limit:
                raise Stalled(float("inf"), atol, used)
            sub, d = self.points(), self.schur.dofs
            wp = w[d] if arc is not None else None
            box = {}

            def G(x):
                state = sub.state(x)
                p = plastic_load(sub, state[-1])
                g0 = self.schur.solve(p) / self.scale
                box["lam"] = frac if arc is None else (ds + start - wp @ p) / along
                return g0 + box["lam"] * self._u_r, p, state

            def load(p):
                return box["lam"] * self._g_r + p

            try:
                x, p, _, count = fixed_point(G, guess[d], _Product(self.schur, self.scale), atol, patience,
                                             limit - used, load)
            except Stalled as stall:
                raise Stalled(stall.force, stall.atol, stall.iterations + used) from None
            used += count
            lam = box["lam"]
            p_full = np.zeros(g.G.shape[1])
            p_full[d] = p
            x_full = ground.backward(ground.forward(p_full, rows), rows) + lam * self.u_r
            state = g.state(x_full)
            flags = state[4].any(axis=1)
            if not (flags & ~self.elements).any():
                return x_full, plastic_load(g, state[-1]), state, used, lam
            self._grow(flags | yielded, GROWTH * LAYERS)
            guess = x_full
        raise GivenUp(guess, used)


class GivenUp(Exception):
    """The zone outgrew :data:`MOST` of the ground: the whole ground's iteration goes on from ``guess``."""

    def __init__(self, guess, used):
        super().__init__(used)
        self.guess, self.used = guess, used

"""The staged plastic solve's iteration on the yielding zone (:func:`solver.stages.plastic._stage_one`,
:func:`~solver.stages.plastic._staged`).

The plastic load is non-zero only on the elements that have yielded, so the unsupported ground's
displacement is ``λ u_r + K⁻¹ p`` with ``p`` on their unknowns. Around them a zone of elements is kept
(where the elastic ground yields at λd and ``GROWTH * LAYERS`` rings around it, grown as the ground
yields). In stage 1 the rest of the ground is eliminated exactly (its Schur complement,
:class:`~solver.fe.condense.RegionSchur`), so each iteration computes strains, returns stresses, mixes and
solves on the zone's points and unknowns only (:meth:`Zone.iterate`): the stresses at the points of the
elements it watches (where it started and :data:`LAYERS` rings round what has yielded), its further rings a
margin to watch more in without refactorizing. In stage 2 the contact acts all round the lining, so the ground
is not condensed: the iteration carries the loads on the zone's and the interface's unknowns, and its solves
sweep only the factor's columns such loads reach (:class:`~solver.stages.plastic._ContactReach`); the stresses
are returned at the watched points alone. What the zone
assumes, that the ground outside what it watches stays elastic, is checked on the whole ground at each answer:
where a point outside has reached yield, it watches more (the zone grown where they would leave it) and the
iteration goes on from there. The zone never shrinks within a stage; one of more than :data:`MOST` of the
ground's unknowns is given up for the whole ground's iteration (its factor would cost more), one of more than
:data:`EARLY` waits until the stage's iterations are many enough to pay for its factor. Zones are kept on the
model (:data:`KEPT` of them): a sweep's cases whose ground yields alike share them.
"""
from __future__ import annotations

from collections import OrderedDict

import numpy as np
import scipy.sparse as sp

from ..fe.condense import RegionSchur
from .path import Stalled, fixed_point

#: Rings of elements kept around the elements at yield.
LAYERS = 2
#: A zone that grows takes this many times :data:`LAYERS` rings around the points at yield.
GROWTH = 2
#: A zone of more than this share of the ground's unknowns is given up (the whole ground's iteration).
MOST = 0.8
#: One of more than this share waits, the stage iterating on the whole ground, until it has spent
#: :data:`AMORTIZE` iterations: zones of 53-77 % made the long solves of weak ground near failure (thousands of
#: iterations) 1.2-1.5 times faster, while one of 71-77 % made a short one (68 iterations) 10 % slower, its
#: factorizations not paid back (``python -m bench.ground --zones 8``, docs/performance.md).
EARLY = 0.65
AMORTIZE = 200
#: Zones (their factors) kept on a model.
KEPT = 3
#: Off: no zone (:mod:`solver.stages.plastic` iterates on the whole ground in both stages, as before zones):
#: what ``python -m bench.ground --zones`` and the tests measure zones against.
ENABLED = True


def _adjacency(model) -> sp.csr_matrix:
    """Elements sharing a vertex (E, E), built once per model."""
    def build():
        t = model.ground.body.basis.mesh.t[:3]
        E = t.shape[1]
        inc = sp.csr_matrix((np.ones(t.size), (t.ravel(), np.tile(np.arange(E), 3))))
        return (inc.T @ inc).tocsr()
    return model.built(("element adjacency",), build)


def dilate(model, elements: np.ndarray, layers: int | None = None) -> np.ndarray:
    """The (E,) mask ``elements`` and ``layers`` (default :data:`LAYERS`) rings of elements around it."""
    adj = _adjacency(model)
    out = elements.copy()
    for _ in range(LAYERS if layers is None else layers):
        out = (adj @ out.astype(float)) > 0
    return out


class Zone:
    """The yielding zone of one stage's solve: the elements it covers (their unknowns: ``dofs``) and, if
    ``condensed`` (stage 1), the ground condensed onto those unknowns; the elements whose points' stresses each
    iteration returns (``watched``: those it started from, where the elastic ground yields at λd in stage 1,
    and :data:`LAYERS` rings round what has yielded), their history from the whole ground's (``gauss``:
    :class:`~solver.stages.points.Points`). The zone's rings beyond them (``GROWTH * LAYERS`` round what has
    yielded) are the margin they grow in without a refactorization. ``u_r`` is the ground's displacement under
    the whole excavation load (stage 1)."""

    def __init__(self, model, gauss, u_r: np.ndarray | None, elements: np.ndarray, layers: int | None = None,
                 condensed: bool = True):
        self.model, self.gauss, self.u_r = model, gauss, u_r
        self.ground, self.condensed = model.ground, condensed
        self.elements = np.zeros(gauss.shape[0], bool)
        self.watched = np.array(elements, bool)  # (and LAYERS rings round what has yielded: :meth:`_cover`)
        self.given_up = self.waiting = False
        self.spent = 0  # iterations of the stage so far (on the zone or the whole ground)
        self._grow(elements, GROWTH * LAYERS if layers is None else layers)

    @property
    def active(self) -> bool:
        return not (self.given_up or self.waiting)

    def _too_big(self, share: float) -> bool:
        """Whether a zone of this ``share`` of the ground is given up or, for now, waits (:data:`EARLY`)."""
        self.given_up = share > MOST
        self.waiting = not self.given_up and share > EARLY and self.spent < AMORTIZE
        return not self.active

    def resume(self) -> None:
        """A zone that waited, once the stage has spent :data:`AMORTIZE` iterations: built now."""
        self.waiting = False
        self._grow(np.zeros_like(self.elements), 0)

    def _grow(self, elements: np.ndarray, layers: int) -> None:
        """Cover ``elements`` too (and ``layers`` rings around them): the unknowns the ground is condensed onto."""
        self.elements = want = self.elements | dilate(self.model, elements, layers)
        gauss = self.gauss
        n = gauss.G.shape[1]
        if self._too_big(want.sum() / want.size):  # (of elements and unknowns alike: about the same share)
            return
        touched = np.zeros(n, bool)
        touched[gauss.G[gauss.rows(np.flatnonzero(want))].indices] = True
        self.dofs = dofs = np.flatnonzero(touched)
        if dofs.size == 0:
            self.given_up = True
        if self.given_up or self._too_big(dofs.size / n):
            return
        if self.condensed:
            self._condense(dofs)
        self._local = np.full(n, -1, np.int64)
        self._local[dofs] = np.arange(dofs.size)
        self._watch(self.watched & want)

    def _watch(self, elements: np.ndarray) -> None:
        """Return the stresses at the points of ``elements`` (within the zone) at each iteration: the zone's rings
        beyond them are the margin its growth needs no refactorization for (:meth:`_holds`)."""
        self.watched = elements
        gauss = self.gauss
        at = np.flatnonzero(elements)
        G = gauss.G[gauss.rows(at)].tocsr()
        G = sp.csr_matrix((G.data, self._local[G.indices], G.indptr), shape=(G.shape[0], self.dofs.size))
        self._at, self._part, self._last = at, gauss.part(at, G), None

    def _condense(self, dofs: np.ndarray) -> None:
        """The ground condensed onto ``dofs`` (kept on the model: :data:`KEPT` zones)."""
        n = self.gauss.G.shape[1]
        model, body = self.model, self.ground.base.body
        cache = model.built(("yielding zones",), OrderedDict)
        key = dofs.tobytes()
        with model._lock:  # a model shared by threads (:func:`solver.model.shared_model`)
            if key not in cache:
                order = self.ground.base.order()  # (the ground's own: no DOF is pinned where zones are made)
                inside = np.zeros(n, bool)
                inside[dofs] = True
                cache[key] = RegionSchur(body.K, order, inside)
                while len(cache) > KEPT:
                    cache.popitem(last=False)
            self.schur = cache[key]
        self.scale = float(getattr(self.ground, "scale", 1.0))
        if self.u_r is not None:  # the excavation load condensed onto the zone (stage 1: release_step)
            self.g_r = self.scale * self.schur.product(self.u_r[dofs])

    def points(self):
        """The zone's points as :class:`~solver.stages.points.Points` (their history as committed)."""
        sub = self.gauss.as_committed(self._part, self._at)
        # the elements that have had a plastic strain and their rows of the zone's gradient operator, as the last
        # points made found them (rows once gathered serve every later iteration while the zone does not grow)
        if self._last is not None:
            sub.yielded = self._last.yielded
        self._last = sub
        return sub

    def solve(self, b: np.ndarray) -> np.ndarray:
        """``K⁻¹ b`` on the zone's unknowns for a load ``b`` on them alone."""
        return self.schur.solve(b) / self.scale

    def iterate(self, plastic_load, setup, guess: np.ndarray, limit: int, patience, atol: float,
                offset: np.ndarray | None = None):
        """:func:`~solver.stages.path.fixed_point` on the zone: ``setup(points, dofs, guess)`` gives the
        iteration's ``G``, start, the start's load (``K`` times it: what its mix carries), ``load`` and ``extend`` (its
        answer's displacement on the whole ground). Returns the whole ground's displacement, plastic load and
        state (at ``offset +`` it) at the answer, and the iterations. Before it, the zone watches the points at
        yield as committed; after it, where a point it does not watch has reached yield, it watches more (grows
        where they would leave it) and the iteration goes on from there."""
        g = self.gauss
        yielded = self._cover()
        used = 0
        while self.active:
            if used >= limit:
                raise Stalled(float("inf"), atol, used)
            G, start, carried, load, extend = setup(self.points(), self.dofs, guess)
            try:
                x, _, _, count = fixed_point(G, start, None, atol, patience, limit - used, load, carried)
            except Stalled as stall:
                raise Stalled(stall.force, stall.atol, stall.iterations + used) from None
            used += count
            x_full = extend(x)
            state = g.state(x_full if offset is None else offset + x_full)
            if self._holds(state, yielded):
                return x_full, plastic_load(g, state[-1]), state, used
            guess = x_full
        raise GivenUp(guess, used)

    def _cover(self) -> np.ndarray:
        """Watch the elements at yield as committed (:meth:`_extend`); those elements."""
        yielded = self.gauss.has_yielded()
        self._extend(yielded)
        return yielded

    def _holds(self, state: tuple, yielded: np.ndarray) -> bool:
        """Whether no point outside the watched elements is at yield in the whole ground's ``state``; else they are
        watched too (:meth:`_extend`) and it is False."""
        flags = state[4].any(axis=1)
        if not (flags & ~self.watched).any():
            return True
        self._extend(flags | yielded)
        return False

    def _extend(self, yielding: np.ndarray) -> None:
        """Watch :data:`LAYERS` rings round the elements ``yielding``, the zone grown to cover them where they
        would leave it (by twice as many rings: each growth refactorizes)."""
        need = dilate(self.model, yielding)
        if self.active and (need & ~self.elements).any():
            self._grow(yielding, GROWTH * LAYERS)
        if self.active and (need & ~self.watched).any():
            self._watch(self.watched | need)


def release_step(zone: Zone, plastic_load, rows, frac=None, arc=None):
    """Stage 1's ``setup`` for :meth:`Zone.iterate` (the plastic load and the excavation load's share ``λ``:
    ``G(x) = K⁻¹p + λ u_r``, at the load ``frac`` or on the arc's plane ``n·(x - x_s) = ds``, whose ``λ`` is
    affine in ``p``: ``n·K⁻¹p = (K⁻¹n)·p``) and the load it reached (``box["lam"]``)."""
    box, plane = {}, {}

    ground = zone.ground

    def setup(sub, d, guess):
        u_r = zone.u_r[d]
        if arc is not None and not plane:  # on the first use: the zone may never be
            x_s, normal, ds = arc
            plane.update(w=ground.backward(ground.forward(normal, rows), rows),
                         at=(ds + float(normal @ x_s)) / float(normal @ zone.u_r), along=float(normal @ zone.u_r))
        wp = plane["w"][d] / plane["along"] if arc is not None else None

        def G(x):
            state = sub.state(x)
            p = plastic_load(sub, state[-1])
            box["lam"] = frac if arc is None else plane["at"] - wp @ p
            return zone.solve(p) + box["lam"] * u_r, p, state

        def extend(x):
            """The whole ground's displacement with ``x`` on the zone: ``λ u_r`` and ``K⁻¹`` of a load on it."""
            base = box["lam"] * zone.u_r
            q = np.zeros(base.size)
            q[d] = zone.scale * zone.schur.product(x - base[d])
            return base + ground.backward(ground.forward(q, rows), rows)

        start = guess[d]
        return G, start, zone.scale * zone.schur.product(start), (lambda p: box["lam"] * zone.g_r + p), extend

    return setup, box


def attempt(zone: Zone | None, on_zone, on_whole, guess: np.ndarray, limit: int):
    """``on_zone()`` while the ``zone`` is small; else, or from where it outgrew :data:`MOST`,
    ``on_whole(guess, limit)``: the iterations (the answers' 4th item) of both counted together (a stall's too)."""
    used = 0
    if zone is not None and zone.waiting and zone.spent >= AMORTIZE:
        zone.resume()
    if zone is not None and zone.active:
        try:
            out = on_zone()
            zone.spent += out[3]
            return out
        except GivenUp as up:
            guess, used = up.guess, up.used
        except Stalled as stall:
            zone.spent += stall.iterations
            raise
    try:
        out = on_whole(guess, limit - used)
    except Stalled as stall:
        if zone is not None:
            zone.spent += stall.iterations + used
        raise Stalled(stall.force, stall.atol, stall.iterations + used) from None
    if zone is not None:
        zone.spent += out[3] + used
    return out[:3] + (out[3] + used,) + out[4:]


def watched(zones: list, model, gauss, plastic_load, setup, whole_G, guess: np.ndarray, K, limit: int, patience,
            atol: float, offset: np.ndarray):
    """Stage 2's equilibrium: on the zone (``setup``, for :meth:`Zone.iterate`: the stresses returned at its
    points, the ground's solves over the factor's columns a load there reaches; ``zones`` holds the stage's, made
    at the first call) while it is small, else :func:`~solver.stages.path.fixed_point` of ``whole_G`` on the whole
    ground: the answer, its plastic load, state and the iterations."""
    if not zones and ENABLED and not model.ground.pinned:  # (a pinned DOF: the factor's unknowns are not the body's)
        zones.append(Zone(model, gauss, None, gauss.has_yielded(), condensed=False))
    return attempt(zones[0] if zones else None,
                   lambda: zones[0].iterate(plastic_load, setup, guess, limit, patience, atol, offset),
                   lambda guess, limit: fixed_point(whole_G, guess, K, atol, patience, limit),
                   guess, limit)


class GivenUp(Exception):
    """The zone outgrew :data:`MOST` of the ground: the whole ground's iteration goes on from ``guess``."""

    def __init__(self, guess, used):
        super().__init__(used)
        self.guess, self.used = guess, used

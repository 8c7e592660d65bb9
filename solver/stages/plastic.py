"""Yielding ground through the construction stages (SPEC §1.5): the staged, incremental solve.

Method: the constant-stiffness ("initial stress") iteration on the model's factorized elastic
stiffness, accelerated by Anderson mixing (:class:`~solver.stages.mixing.Anderson`). With ``ε_p`` the plastic
strain, the ground's equilibrium ``∫Bᵀ(σ - σ0′) = f`` reads ``K u = f + p(u)`` with the
plastic load ``p = ∫Bᵀ(σ0′ + D ε(u) - σ(u))``, non-zero only where the ground yields. Each
iteration solves the *elastic* problem with the load ``f + p``: one forward and one backward
triangular solve on the factors the model already holds and, in stage 2, the contact problem on
the same interface flexibility (so the bolt search, every interface model, water and layers
work unchanged). A sweep over loads, K0, λd or strength therefore still shares one model per
geometry. The stop test is the equilibrium residual: the out-of-balance force
``‖K u - f - p(u)‖`` of the iterate, at most ``solver.plastic_tolerance`` of the increment's load
(SPEC §9.1: stage 1's λd/n of the excavation load; stage 2's 1/n of its own loads, or stage 1's
where larger); the plastic consistency holds at every point by the return
mapping (:mod:`solver.ground.mohr_coulomb`, :mod:`solver.ground.hoek_brown`). The iteration runs on the
yielding zone (:mod:`solver.stages.region`): in stage 1 on its unknowns alone, the elastic rest of the ground
condensed out exactly; in stage 2 on the whole ground with the stresses returned at the zone's points; the
whole ground checked at every answer.

Where a load step stalls (:data:`~solver.stages.path.STAGNATION`) it is halved, and the steps grow again as they
converge (:func:`~solver.stages.path.advance`; the automatic step control of commercial codes). Where a stage-1 step
of 1/8 of its increment still stalls, the path has a local limit point: with flow far from
associated (ψ = 0 against φ = 25°) a shear band forming in the unsupported ground makes the load it
holds dip by a few per cent of an increment and rise again (a snap-through). Load control cannot
pass it; arc-length steps (Riks) follow the path through, the load solved from the arc's plane at
each iterate (``G`` is affine in the load, so the arc costs nothing per iteration). A path whose
load falls by more than half an increment below its peak, or whose displacement doubles for less
than 1 % of an increment's load, has passed or reached the ground's limit load: the unsupported
ground collapses, and the error says so with what it held. A case whose solve fails short of a
collapse is solved once more at half ``solver.plastic_tolerance`` (:func:`tightened`). The consistent tangent is not
used: along these shear-band modes its Newton step leaves the region where its linearization holds
(issue 25's measurements, docs/performance.md).

Stages (SPEC §1.1): stage 1 releases λd of the excavation load in ``solver.load_steps``
equal increments on the unsupported ground (those below the first yield, :func:`first_yield`,
in one elastic solve; each increment starts from the last one's displacement change, scaled
to its length); the lining is placed on the ground as it stands; stage 2
releases the rest (with the lining's weight, the water and a drained lining's seepage) in as
many increments, each with its contact solve. The stress history lives at the quadrature
points (degree 4, six per triangle); the stored face stresses are followed, with the same
history, at the sub-triangle centroids. Strains come from one sparse gradient operator per
set of points (:meth:`~solver.model.TunnelModel.gradient_operator`), whose transpose
integrates the plastic load.
"""
from __future__ import annotations

import logging

import numpy as np

from ..errors import GroundCollapseError, NotConvergedError
from ..ground.loads import in_situ_stress, moduli
from ..ground.laws import PointLaws
from ..ground.mohr_coulomb import equivalent
from ..ground.strata import strata
from ..results.post import mean_convergence
from ..spec.canonical import canonical_json
from ..spec.case import PLASTIC_SOLVER_FIELDS
from .contact import contact_tractions
from .loads import stage_loads
from . import path
from .path import advance, fixed_point
from . import region
from .region import Zone
from .recovery import finish
from .state import Forward, StageLoads

log = logging.getLogger(__name__)

#: Where a case's plastic solve fails short of a collapse, it is solved once more at this fraction of
#: ``solver.plastic_tolerance`` (:func:`tightened`).
RETRY_TOLERANCE = 0.5
#: The least distance from the yield surface (relative) at which a point is reported at yield:
#: a tenth of ``solver.plastic_tolerance`` if coarser (the iteration leaves yielding points a hair inside).
FLAG_TOLERANCE = 1e-3


class _Points:
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
        self.lam, self.mu, self.mu2 = lam, mu, 2 * mu
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
        #: rows of ``G``, transposed (:func:`_plastic_load`)
        self.yielded = (np.zeros(y.shape[0], bool), None, None)
        #: a point within this (relative) distance of the yield surface counts as at yield: the
        #: equilibrium iteration's tolerance leaves yielding points a hair inside it
        self.flag_tolerance = max(spec.solver.plastic_tolerance / 10, FLAG_TOLERANCE)

    def hooke(self, grad: np.ndarray, onto: np.ndarray | None = None) -> np.ndarray:
        """The elastic stress (4, E, Q) of a displacement gradient (2, 2, E, Q), plane strain;
        added to a copy of ``onto`` (4, E, Q) if given (in place: the trial of every iterate)."""
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

    def trial(self, grad: np.ndarray):
        """Stress, plastic strain increment, yield flags and ``D ε_p`` of a displacement
        gradient since excavation, from the last converged increment."""
        trial = self.hooke(grad - self.grad, onto=self.sigma)
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
        return stress, dep, flags.reshape(self.shape), self.tau + (trial - stress)

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


def _plastic_load(points: _Points, tau: np.ndarray) -> np.ndarray:
    """``∫Bᵀ(σ0′ + D ε(u) - σ)`` on the ground's unknowns, at the quadrature points of
    ``points``, from ``tau`` = the bracket (4, E, Q): non-zero only where the ground has yielded,
    so only the rows of the gradient operator at the points of the elements that have yielded
    so far are used (:attr:`_Points.yielded`, grown when others yield)."""
    elements, at, GT = points.yielded
    now = (tau.reshape(4, -1) != 0).any(axis=0).reshape(points.shape).any(axis=1)  # (E,)
    if (now & ~elements).any():
        elements = elements | now
        E, Q = points.shape
        at = (np.flatnonzero(elements)[:, None] * Q + np.arange(Q)).ravel()  # their points
        GT = points.G[(np.arange(4)[:, None] * (E * Q) + at[None, :]).ravel()].T
        points.yielded = elements, at, GT
    if GT is None:
        return np.zeros(points.G.shape[1])
    w = points.weights.reshape(-1)[at]
    t = tau.reshape(4, -1)[:, at]
    return GT @ np.concatenate([t[0] * w, t[2] * w, t[2] * w, t[1] * w])


def first_yield(points: _Points, u_unit: np.ndarray, limit: float) -> float:
    """The largest fraction ``f`` ≤ ``limit`` of the displacement ``u_unit`` (added to the last
    converged state) for which every point's stress stays inside its yield surface. The stress
    is linear in ``f`` and the yield function convex in the stress, so each point's admissible
    fractions are an interval ``[0, f_i]``: a point inside at ``limit`` is inside all the way,
    and the bisection (to 1e-4 of ``limit``, from below) looks only at the points that are not."""
    if not points.yielding.any():
        return limit
    rate = points.hooke(points.gradient(u_unit)).reshape(4, -1)[:, points.yielding]
    start = points.sigma.reshape(4, -1)[:, points.yielding]

    def at_yield(f: float, where, material) -> np.ndarray:
        return material.return_stress(start[:, where] + f * rate[:, where], points.flag_tolerance)[2]

    everywhere = slice(None)
    out = np.flatnonzero(at_yield(limit, everywhere, points.material))
    if out.size == 0:
        return limit
    material = points.material.at(out)
    low, high = 0.0, limit
    while high - low > 1e-4 * limit:
        mid = 0.5 * (low + high)
        low, high = (low, mid) if at_yield(mid, out, material).any() else (mid, high)
    return low


#: What stage 1 does not depend on: the lining's weight (its stiffness is the model's), the interface, the
#: design checks and the report (:func:`stage_one_key`).
_STAGE_TWO = ("lining", "interface", "design", "settlement", "name")


def stage_one_key(spec, rows, tol: float | None = None) -> str:
    """What the unsupported ground's release depends on beyond its model (:class:`~solver.build.Kept`):
    the case less :data:`_STAGE_TWO`; of the solver its steps and stop test (``tol`` too: a retry's own, or
    none where the caller retries), and the factorization's ``rows`` (another interface model's
    factorization solves the same equations with other rounding)."""
    contact = set(type(spec.solver).model_fields) - set(PLASTIC_SOLVER_FIELDS)
    return f"{canonical_json(spec, exclude={**dict.fromkeys(_STAGE_TWO, True), 'solver': contact})}|{tol!r}|{rows}"


def _first_stage(model, spec, rows, release, ld: float, tol: float, points: tuple, commit):
    """Stage 1 of a case (:func:`_stage_one`), kept on its model by :func:`stage_one_key` with the
    histories of its ``points`` (restored into them on a later case): a sweep on one model whose
    cases differ only in the lining's weight, the interface's strength or the solver's contact
    settings solves it once, with the answer a fresh model gives (a design sweep takes the whole
    solution: :meth:`solver.model.TunnelModel.solve`). A stage 1 that
    failed fails the later cases alike, without solving it again."""

    def compute():
        u1, p1, iterations, curve = _stage_one(model, rows, release, ld, spec.solver.load_steps, tol, points[0], commit)
        u1.flags.writeable = p1.flags.writeable = False
        return (u1, p1, iterations, tuple(curve)), [p.history() for p in points]

    kept = model.kept.get("stage one", stage_one_key(spec, rows, tol), compute, failures=(NotConvergedError,))
    (u1, p1, iterations, curve), histories = kept
    for p, history in zip(points, histories):
        p.restore(history)
    return u1, p1, iterations, list(curve)


def _stage_one(model, rows, release, ld: float, steps: int, tol: float, gauss: "_Points", commit=None):
    """Stage 1: λd r on the unsupported ground in ``steps`` equal increments; those the ground
    takes elastically in one solve (up to its first yield). Returns the free-DOF displacement,
    the plastic load, the iterations and the ground reaction curve [(released, convergence)].
    ``commit(*state)`` stores a converged state (:meth:`_Points.state`; default: ``gauss``'s history)."""
    commit = commit or (lambda u_free, *state: gauss.commit(*state))
    ground = model.ground
    body, iface = ground.body, model.mesh.interface
    K = ground.stiffness()
    iterations, curve = 0, []
    u1 = np.zeros(body.n)
    p1 = np.zeros(body.n)
    if release is not None and ld > 0:
        y_r = ground.forward(release, rows)
        u_r = ground.backward(y_r, rows)
        start = first_yield(gauss, u_r, ld)
        elastic = int(np.floor(start / ld * steps * (1 + 1e-12)))
        if elastic:
            u1 = ld * elastic / steps * u_r
            commit(*gauss.state(u1))
            reached = mean_convergence(body.expand(u1), iface)  # linear in the load up to here
            curve.extend((ld * k / steps, reached * k / elastic) for k in range(1, elastic + 1))
        u1_prev = u1 - ld / steps * u_r

        atol = tol * ld / steps * float(np.linalg.norm(release))  # of the increment's load (SPEC §9.1)

        zones = []  # the zone the ground yields in (built at the first plastic step)

        def solve1(guess, limit, patience, frac=None, arc=None):
            """Equilibrium at the load ``frac`` (load control) or, with ``arc`` = (x_s, n, ds), on the
            plane ``n·(x - x_s) = ds`` at the load that plane asks of each iterate (arc-length: the
            load is affine in it, ``G(x) = K⁺p(x) + λ(x) u_r``). Returns the :func:`~solver.stages.path.fixed_point`
            answer and its load: on the yielding zone (:mod:`solver.stages.region`) while it is small, else
            on the whole ground."""
            if not zones and not ground.pinned and region.ENABLED:  # where it yields at λd on the elastic ground
                zones.append(Zone(model, gauss, u_r, gauss.trial(gauss.gradient(ld * u_r))[2].any(axis=1)))
            setup, box = region.release_step(zones[0], _plastic_load, rows, frac, arc) if zones else (None, {})

            def on_zone():
                return zones[0].iterate(_plastic_load, rows, setup, guess, limit, patience, atol) + (box["lam"],)

            def on_whole(guess, limit):
                def G(x):
                    state = gauss.state(x)
                    p = _plastic_load(gauss, state[-1])
                    g0 = ground.backward(ground.forward(p, rows), rows)
                    if arc is None:
                        box["lam"] = frac
                    else:
                        x_s, n, ds = arc
                        box["lam"] = (ds - n @ (g0 - x_s)) / (n @ u_r)
                    return g0 + box["lam"] * u_r, p, state

                # the load G solves for: K K⁺ f = f where no DOF is pinned (the ground's boundary holds it)
                load = None if ground.pinned else (lambda p: box["lam"] * release + p)
                return fixed_point(G, guess, K, atol, patience, limit, load) + (box["lam"],)

            return region.attempt(zones[0] if zones else None, on_zone, on_whole, guess, limit)

        lam, lam_prev, h = ld * elastic / steps, ld * (elastic - 1) / steps, ld / steps
        for k in range(elastic + 1, steps + 1):
            where = f"stage 1, increment {k} of {steps}"
            try:  # the plastic increments share the stage's iterations (path.share)
                u1, p1, its, u1_prev, lam_prev, h = advance(solve1, commit, u1, u1_prev, lam, lam_prev,
                                                             ld * k / steps, ld / steps, h, where,
                                                             budget=path.share(k - elastic, iterations))
            except NotConvergedError as err:
                unit = mean_convergence(body.expand(u_r), iface)  # the elastic ground's, of the whole release
                raise type(err)(f"{err}. {held(curve, unit, isinstance(err, GroundCollapseError))}") from None
            lam = ld * k / steps
            iterations += its
            curve.append((lam, mean_convergence(body.expand(u1), iface)))
    return u1, p1, iterations, curve


def held(curve: list[tuple[float, float]], unit: float, collapse: bool = False) -> str:
    """What the unsupported ground held before a stage-1 increment failed, for the failure's
    message: the last converged release on the ground reaction ``curve`` [(released, mean
    convergence)], its convergence against the elastic ground's (``unit``: the elastic mean
    convergence of the whole excavation load) and how steep the curve had become. Near a
    mechanism the curve steepens without bound (the last increment many times as steep as the
    elastic line); a stall with the curve still near elastic is the iteration's, not the ground's.
    After a ``collapse`` (whose error names the largest load held) the last full increment is told as such."""
    if not curve or unit == 0:
        return "The ground yielded within the first increment: no release converged on the unsupported ground"
    (l0, c0), (l1, c1) = ((0.0, 0.0), curve[-1]) if len(curve) == 1 else curve[-2:]
    lead = "Its last full increment reached" if collapse else "The unsupported ground held"
    return (f"{lead} λd {l1:.3g} (mean wall convergence {1e3 * c1:.3g} mm, "
            f"{c1 / (l1 * unit):.3g} times the elastic ground's; the ground reaction curve's last "
            f"increment {(c1 - c0) / ((l1 - l0) * unit):.3g} times as steep as the elastic line)")


def release_unsupported(model, spec, rows, fraction: float = 1.0):
    """Stage 1 alone: ``fraction`` of the excavation load released on the unsupported ground in
    ``solver.load_steps`` increments (as :func:`solve_staged` begins). Returns the ground reaction
    curve [(released, convergence)] and the quadrature points' history (:class:`_Points`: where
    the ground yielded). Raises :class:`NotConvergedError` where the ground collapses."""
    release = stage_loads(model, spec).release

    def attempt(tol: float):
        gauss = _Points(model, spec, "gauss")
        return _stage_one(model, rows, release, fraction, spec.solver.load_steps, tol, gauss)[3], gauss

    return tightened(attempt, spec.solver.plastic_tolerance)[0]


def tightened(attempt, tol: float):
    """``attempt(tol)``, and where it fails short of a collapse, ``attempt`` once more at
    :data:`RETRY_TOLERANCE` × ``tol``: the answer (a stricter stop test than asked, so also the asked
    one's) and, if retried, the first attempt's reason; raises the second's with both.

    Why: the path a loose stop test leaves (each increment's out-of-balance force up to the
    tolerance) can meet a limit point in non-associated ground that the path of a tighter one
    does not (docs/performance.md: issue 36's weak case 3 turns into elastic unloading past λ 0.157
    at 0.01 and converges at 0.005)."""
    try:
        return attempt(tol), None
    except GroundCollapseError:
        raise
    except NotConvergedError as first:
        log.info("yielding ground at solver.plastic_tolerance %g: %s; again at %g", tol, first, RETRY_TOLERANCE * tol)
        try:
            return attempt(RETRY_TOLERANCE * tol), str(first)
        except NotConvergedError as again:
            raise type(again)(f"{again} (at solver.plastic_tolerance {RETRY_TOLERANCE * tol:g}; at {tol:g}: "
                              f"{first})") from None


def solve_staged(model, spec, rows, t0: float):
    """Solve a case whose ground can yield (see the module's docstring): a
    :class:`~solver.model.Solution` with ``plastic`` results filled (:func:`tightened`: where the
    stop test asked stalls, once more at a tighter one, which ``plastic["retried"]`` reports)."""
    sol, first = tightened(lambda tol: _staged(model, spec, rows, t0, tol), spec.solver.plastic_tolerance)
    sol.plastic["retried"] = None if first is None else (RETRY_TOLERANCE * spec.solver.plastic_tolerance, first)
    return sol


def _staged(model, spec, rows, t0: float, tol: float):
    ground, lining = model.ground, model.lining
    body = ground.body
    gauss = _Points(model, spec, "gauss")
    out = _Points(model, spec, "points")
    loads = stage_loads(model, spec)
    steps = spec.solver.load_steps
    ld = spec.excavation.deconfinement if loads.release is not None else 0.0
    K = ground.stiffness()

    def commit(u_free, grad, stress, dep, flags, tau):
        gauss.commit(grad, stress, dep, flags, tau)
        og = out.gradient(u_free)
        out.commit(og, *out.trial(og))

    u1, p1, iterations, curve = _first_stage(model, spec, rows, loads.release, ld, tol, (gauss, out), commit)
    stage1 = out.at_yield.reshape(-1).copy()  # the ground that yielded before the lining was placed
    # stage 2: the rest, with the lining and contact
    full = StageLoads(loads.ground, loads.lining, None, loads.seepage)
    y_g = ground.forward(full.ground, rows)
    y_l = lining.forward(full.lining, rows)
    F2_full = model.mode_loads(full.lining)
    u2 = u2_prev = np.zeros(body.n)
    p = p1

    def stage_of(p, a):
        """The contact stage's loads at the fraction ``a``, their forward halves and interface jumps."""
        extra = p - p1
        stage = Forward(ground=a * y_g + ground.forward(extra, rows), lining=a * y_l)
        jumps = ground.jumps(stage.ground, rows) + lining.jumps(stage.lining, rows)
        return StageLoads(a * full.ground + extra, a * full.lining, None), stage, jumps

    # the increment's load: 1/n of the stage's own, or stage 1's where larger (the lining placed
    # on ground released in full, stage 2 carries little more than its weight)
    own = float(np.linalg.norm(full.ground)) + float(np.sum(np.abs(F2_full)))
    first = ld * float(np.linalg.norm(loads.release)) if loads.release is not None else 0.0
    atol = tol * max(own, first) / steps

    zones = []  # the points whose stresses are returned (:meth:`solver.stages.region.Zone.watch`)

    def solve2(guess, limit, patience, frac):

        def make_G(points, dofs):
            def G(x):
                state = points.state((u1 + x)[dofs])
                p = np.zeros(body.n)
                p[dofs] = _plastic_load(points, state[-1])
                _, stage, d = stage_of(p, frac)
                _, t = contact_tractions(model, spec, d, frac * F2_full)
                return ground.backward(stage.ground, rows, model.w * t), p, state
            return G

        return region.watched(zones, model, gauss, _plastic_load, make_G, guess, K, limit, patience, atol, u1) + (frac,)

    a, a_prev, h, used = 0.0, -1.0 / steps, 1.0 / steps, 0
    for k in range(1, steps + 1):
        u2, p, its, u2_prev, a_prev, h = advance(solve2, commit, u2, u2_prev, a, a_prev, k / steps, 1.0 / steps, h,
                                                  f"stage 2, increment {k} of {steps}", arc_length=False,
                                                  budget=path.share(k, used))
        a = k / steps
        used += its
    iterations += used
    # the whole contact stage (both bodies, the checks) of the last increment's converged iterate
    sol = finish(model, spec, rows, *stage_of(p, 1.0), F2_full, t0, u1=u1)
    E = out.shape[0]
    sol.plastic = {
        "stress": out.sigma.reshape(4, -1),
        "at_yield": out.at_yield.reshape(-1),
        "stage1_at_yield": stage1,
        "eqps": out.eqps.reshape(-1),
        "iterations": iterations,
        "ground_reaction": curve,
        "elements": E,
    }
    return sol

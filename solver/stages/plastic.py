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
condensed out exactly; in stage 2 on the loads of the zone's and the interface's unknowns, the solves over the
factor's columns such loads reach (:class:`_ContactReach`); the whole ground checked at every answer.

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
equal increments on the unsupported ground (those below the first yield,
:func:`~solver.stages.points.elastic_increments`, in one elastic solve; each increment starts from the last
one's displacement change, scaled to its length); the lining is placed on the ground as it stands; stage 2
releases the rest (with the lining's weight, the water and a drained lining's seepage) in as
many increments, each with its contact solve (those below the first yield again in one solve where
there is no gap: :func:`_elastic_contact`). The stress history lives at the quadrature
points (degree 4, six per triangle); the stored face stresses are followed, with the same
history, at the sub-triangle centroids (at each step where the ground may yield:
:func:`~solver.stages.points.follows`; everywhere at the end). Strains come from one sparse gradient operator per
set of points (:meth:`~solver.model.TunnelModel.gradient_operator`), whose transpose
integrates the plastic load.
"""
from __future__ import annotations

import logging

import numpy as np

from ..errors import GroundCollapseError, NotConvergedError
from ..results.post import mean_convergence
from ..spec.canonical import canonical_json
from ..spec.case import PLASTIC_SOLVER_FIELDS
from ..fe.condense import Reach
from .contact import contact_tractions
from .loads import stage_loads
from .points import Points, affine_elements, elastic_increments, follows, plastic_load
from . import bounds, path
from .path import advance, fixed_point
from . import region
from .region import Zone
from .recovery import finish
from .state import Forward, StageLoads

log = logging.getLogger(__name__)

#: Where a case's plastic solve fails short of a collapse, it is solved once more at this fraction of
#: ``solver.plastic_tolerance`` (:func:`tightened`).
RETRY_TOLERANCE = 0.5
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


def _stage_one(model, rows, release, ld: float, steps: int, tol: float, gauss: "Points", commit=None):
    """Stage 1: λd r on the unsupported ground in ``steps`` equal increments; those the ground
    takes elastically in one solve (up to its first yield). Returns the free-DOF displacement,
    the plastic load, the iterations and the ground reaction curve [(released, convergence)].
    ``commit(*state)`` stores a converged state (:meth:`Points.state`; default: ``gauss``'s history)."""
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
        elastic, at_end = elastic_increments(gauss, ld * u_r, steps)
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
                zones.append(Zone(model, gauss, u_r, at_end))  # where the elastic ground yields at λd
            setup, box = region.release_step(zones[0], plastic_load, rows, frac, arc) if zones else (None, {})

            def on_zone():
                return zones[0].iterate(plastic_load, setup, guess, limit, patience, atol) + (box["lam"],)

            def on_whole(guess, limit):
                def G(x):
                    state = gauss.state(x)
                    p = plastic_load(gauss, state[-1])
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
                again = type(err)(f"{err}. {held(curve, unit, isinstance(err, GroundCollapseError))}")
                again.__dict__.update(err.__dict__, unsupported=True)  # stage 1's: the ground alone failed
                raise again from None
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


def release_unsupported(model, spec, rows, fraction: float = 1.0, retry: bool = True):
    """Stage 1 alone: ``fraction`` of the excavation load released on the unsupported ground in
    ``solver.load_steps`` increments (as :func:`solve_staged` begins). Returns the ground reaction
    curve [(released, convergence)] and the quadrature points' history (:class:`Points`: where
    the ground yielded). Raises :class:`NotConvergedError` where the ground collapses, or where it
    stalls (with ``retry``, once more at a tighter stop test first: :func:`tightened`)."""
    release = stage_loads(model, spec).release

    def attempt(tol: float):
        gauss = Points(model, spec, "gauss")
        return _stage_one(model, rows, release, fraction, spec.solver.load_steps, tol, gauss)[3], gauss

    return tightened(attempt, spec.solver.plastic_tolerance)[0] if retry else attempt(spec.solver.plastic_tolerance)


def tightened(attempt, tol: float, bound=None):
    """``attempt(tol)``, and where it fails short of a collapse, ``attempt`` once more at
    :data:`RETRY_TOLERANCE` × ``tol``: the answer (a stricter stop test than asked, so also the asked
    one's) and, if retried, the first attempt's reason; raises the second's with both. A collapse is
    not retried, unless ``bound(failure)`` (if given; :func:`~solver.stages.bounds.judge`: for a failure
    in stage 1) finds it below what the ground holds for certain; a stall it proves a collapse is not either.

    Why: the path a loose stop test leaves (each increment's out-of-balance force up to the
    tolerance) can meet a limit point in non-associated ground that the path of a tighter one
    does not (docs/performance.md: issue 36's weak case 3 turns into elastic unloading past λ 0.157
    at 0.01 and converges at 0.005)."""
    def judged(failure) -> str:
        """The failure's reason, judged by ``bound`` where it can be (raising what that proves or confirms)."""
        if bound is not None and getattr(failure, "unsupported", False):
            note = bound(failure)  # raises the collapse it proves, or a named one it does not contradict
            return f"{failure} ({note})" if note else str(failure)
        if isinstance(failure, GroundCollapseError):
            raise failure
        return str(failure)

    try:
        return attempt(tol), None
    except NotConvergedError as failed:
        first = judged(failed)
    log.info("yielding ground at solver.plastic_tolerance %g: %s; again at %g", tol, first, RETRY_TOLERANCE * tol)
    try:
        return attempt(RETRY_TOLERANCE * tol), first
    except NotConvergedError as failed:
        again = judged(failed)
    raise NotConvergedError(f"{again} (at solver.plastic_tolerance {RETRY_TOLERANCE * tol:g}; at {tol:g}: "
                            f"{first})") from None


def _elastic_contact(model, spec, rows, gauss: Points, stage_of, p1, F2_full, steps: int, commit, u1):
    """The contact stage's first increments that no point flows in, in one solve: how many, the displacement
    at their end and one increment before it (zeros where none). With no gap (SPEC §1.2's ``gap`` 0) every
    contact model is positively homogeneous (cone constraints: the tractions of ``a`` times the loads are ``a``
    times theirs), so with no point flowing the stage's displacement is ``a x`` with ``x`` its elastic answer,
    each point's stress is linear in ``a`` and, the yield function being convex, inside its surface all the way
    to the first yield (:func:`~solver.stages.points.elastic_increments`): the increments below it are the
    incremental path's answer, exactly. (A gap makes the contact's answer affine, not linear, in the load: all
    increments are then solved.)"""
    zero = np.zeros(model.ground.body.n)
    if spec.geometry.gap != 0:
        return 0, zero, zero
    _, stage, d = stage_of(p1, 1.0)
    _, t = contact_tractions(model, spec, d, F2_full)
    x = model.ground.backward(stage.ground, rows, model.w * t)
    elastic, _ = elastic_increments(gauss, x, steps)
    if elastic:
        commit(*gauss.state(u1 + elastic / steps * x))
    return elastic, elastic / steps * x, (elastic - 1) / steps * x


class _ContactReach:
    """The contact stage's iteration on a yielding zone (:meth:`~solver.stages.region.Zone.iterate`'s ``setup``),
    on the loads: at the load's fraction ``a`` the ground's displacement is ``a u_f + K⁻¹ l`` (``u_f`` of the
    stage's loads) with ``l = p_x - p1 - Bᵀ W t`` on the zone's and the interface's unknowns (the stage's plastic
    load and the contact's tractions), so each iterate is that load and its forward solve ``y = L⁻¹ P l``, which
    the mix carries alike: the zone's displacements are ``y``'s backward solve, its plastic load's jumps its
    forward solve, both over the factor's columns a load on those unknowns reaches alone
    (:class:`~solver.fe.condense.Reach`), and the out-of-balance force is the change of ``l``: the whole
    ground's iteration (:func:`_staged`'s ``G``) to rounding. At an answer one backward solve over the whole
    factor gives the whole ground's displacement."""

    def __init__(self, model, spec, rows, K, f_full, y_g, y_l, F2_full, u1, p1):
        self.model, self.spec, self.rows, self.F2, self.u1, self.p1 = model, spec, rows, F2_full, u1, p1
        self.K = K  # the ground's stiffness (a scaled body's a scaled copy: made once)
        self.factor, self.on_last = model.ground.factor(rows)
        self.last = np.asarray(self.factor.last)
        self._f, self._y = f_full, (y_g, y_l)
        self._fixed = self._reach = None

    def fixed(self):
        """``u_f`` and the jumps of the stage's loads, ground's and lining's (at the first use)."""
        if self._fixed is None:
            (y_g, y_l), ground, rows = self._y, self.model.ground, self.rows
            self._fixed = ground.backward(y_g, rows), ground.jumps(y_g, rows) + self.model.lining.jumps(y_l, rows)
        return self._fixed

    def reach(self, d: np.ndarray):
        """The zone's unknowns ``d`` with the interface's, where they sit among them, and their :class:`Reach`
        (kept while ``d`` does not change)."""
        if self._reach is None or not np.array_equal(self._reach[0], d):
            D = np.union1d(d, self.last)
            self._reach = (d, D, np.searchsorted(D, d), np.searchsorted(D, self.last), Reach(self.factor, D))
        return self._reach[1:]

    def setup(self, frac: float):
        u_f, jumps_f = self.fixed()
        model, on_last, ground = self.model, self.on_last, self.model.ground
        served, scale = on_last.shape[0], float(getattr(ground, "scale", 1.0))
        k = self.factor.k

        def setup(sub, d, guess):
            D, at_d, at_last, reach = self.reach(d)
            load0 = (self.K @ guess - frac * self._f)[D]  # the start's (exact for the path's answers)
            start, base, p1 = self.u1[d] + frac * u_f[d], frac * u_f, self.p1[d]

            def G(y):
                state = sub.state(start + reach.at(reach.backward(y))[at_d] / scale)
                extra = plastic_load(sub, state[-1]) - p1
                load = np.zeros(D.size)
                load[at_d] = extra
                y_new = reach.forward(load)
                _, t = contact_tractions(model, self.spec, frac * jumps_f + on_last @ self.factor.interface_of(
                    y_new[-k:]) / scale, frac * self.F2)
                g = on_last.T @ (model.w * t)[:served]  # Bᵀ W t on the interface's unknowns (their load: -g)
                load[at_last] -= g
                y_new[-k:] -= self.factor.lift_of(g)
                return y_new, load, state

            def extend(y):
                full = np.zeros(self.factor.n)
                full[reach.columns] = y
                return base + ground.backward(full, self.rows)

            return G, reach.forward(load0), load0, (lambda load: load), extend

        return setup


def _committing(model, spec, gauss: Points, out: Points):
    """``commit(*state)`` of a converged state: the quadrature points' history, and the stored faces' points' where
    the ground may yield (elsewhere elastic: exact, :func:`~solver.stages.points.follows`; with water the in-situ
    pore pressure kinks at the table within a triangle: all followed), with a margin of rings grown only when they
    yield beyond it (each new set gathers its rows of the gradient operator). All are followed at the end."""
    affine = affine_elements(model) if spec.water.table is None else None
    followed = np.zeros(gauss.shape[0], bool)

    def commit(u_free, grad, stress, dep, flags, tau):
        nonlocal followed
        gauss.commit(grad, stress, dep, flags, tau)
        if affine is not None:
            need = follows(gauss, out, affine)
            if (need & ~followed).any():
                followed = followed | region.dilate(model, need)
        out.follow(u_free, None if affine is None else followed)

    return commit


def solve_staged(model, spec, rows, t0: float):
    """Solve a case whose ground can yield (see the module's docstring): a
    :class:`~solver.model.Solution` with ``plastic`` results filled (:func:`tightened`: where the
    stop test asked stalls, once more at a tighter one, which ``plastic["retried"]`` reports)."""
    def release(twin):  # a twin case's stage 1 alone (a stall proves nothing: not retried); its outcome kept
        def stands():
            release_unsupported(model, twin, rows, twin.excavation.deconfinement, retry=False)
            return True
        return model.kept.get("bound", stage_one_key(twin, rows), stands, failures=(NotConvergedError,))

    sol, first = tightened(lambda tol: _staged(model, spec, rows, t0, tol), spec.solver.plastic_tolerance,
                           lambda failed: bounds.judge(spec, failed, release))
    sol.plastic["retried"] = None if first is None else (RETRY_TOLERANCE * spec.solver.plastic_tolerance, first)
    return sol


def _staged(model, spec, rows, t0: float, tol: float):
    ground, lining = model.ground, model.lining
    body = ground.body
    gauss = Points(model, spec, "gauss")
    out = Points(model, spec, "points")
    loads = stage_loads(model, spec)
    steps = spec.solver.load_steps
    ld = spec.excavation.deconfinement if loads.release is not None else 0.0
    K = ground.stiffness()

    commit = _committing(model, spec, gauss, out)

    u1, p1, iterations, curve = _first_stage(model, spec, rows, loads.release, ld, tol, (gauss, out), commit)
    stage1 = out.at_yield.reshape(-1).copy()  # the ground that yielded before the lining was placed
    # stage 2: the rest, with the lining and contact
    full = StageLoads(loads.ground, loads.lining, None, loads.seepage)
    y_g = ground.forward(full.ground, rows)
    y_l = lining.forward(full.lining, rows)
    F2_full = model.mode_loads(full.lining)
    p = p1

    def stage_of(p, a):
        """The contact stage's loads at the fraction ``a``, their forward halves and interface jumps."""
        extra = p - p1
        moved = ground.forward(extra, rows) if extra.any() else 0.0  # (none where no point has flowed since)
        stage = Forward(ground=a * y_g + moved, lining=a * y_l)
        jumps = ground.jumps(stage.ground, rows) + lining.jumps(stage.lining, rows)
        return StageLoads(a * full.ground + extra, a * full.lining, None), stage, jumps

    # the increment's load: 1/n of the stage's own, or stage 1's where larger (the lining placed
    # on ground released in full, stage 2 carries little more than its weight)
    own = float(np.linalg.norm(full.ground)) + float(np.sum(np.abs(F2_full)))
    first = ld * float(np.linalg.norm(loads.release)) if loads.release is not None else 0.0
    atol = tol * max(own, first) / steps

    zones = []  # the points whose stresses are returned (:meth:`solver.stages.region.Zone.iterate`)
    contact = _ContactReach(model, spec, rows, K, full.ground, y_g, y_l, F2_full, u1, p1)

    def solve2(guess, limit, patience, frac):
        def G(x):  # on the whole ground, where the zone is given up
            state = gauss.state(u1 + x)
            p = plastic_load(gauss, state[-1])
            _, stage, d = stage_of(p, frac)
            _, t = contact_tractions(model, spec, d, frac * F2_full)
            return ground.backward(stage.ground, rows, model.w * t), p, state

        return region.watched(zones, model, gauss, plastic_load, contact.setup(frac), G, guess, K, limit, patience,
                              atol, u1) + (frac,)

    elastic, u2, u2_prev = _elastic_contact(model, spec, rows, gauss, stage_of, p1, F2_full, steps, commit, u1)
    a, a_prev, h, used = elastic / steps, (elastic - 1) / steps, 1.0 / steps, 0
    for k in range(elastic + 1, steps + 1):
        u2, p, its, u2_prev, a_prev, h = advance(solve2, commit, u2, u2_prev, a, a_prev, k / steps, 1.0 / steps, h,
                                                  f"stage 2, increment {k} of {steps}", arc_length=False,
                                                  budget=path.share(k - elastic, used))
        a = k / steps
        used += its
    iterations += used
    out.follow(u1 + u2)  # every stored face's point at the end
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

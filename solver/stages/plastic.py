"""Yielding ground through the construction stages (SPEC §1.5, §9.1): the staged, incremental solve.

Method: each load increment's equilibrium ``K u = f + p(u)`` (``p`` the plastic load,
:mod:`.points`) is solved by Newton's method on the consistent tangent of the ground's laws, its
linear systems by GMRES preconditioned by the elastic factorization the model already holds, with
a line search (:func:`.newton.newton`): the preconditioned Jacobian ``I - K⁻¹P′`` is the identity
but for the points that yield, so a Newton step costs a few triangular solve pairs, and no matrix
is assembled or factorized per case. A sweep over loads, K0, λd or strength therefore still shares
one model per geometry. In stage 2 the contact problem is solved on the interface flexibility at
every iterate, as in an elastic case (every interface model, water, layers and segmental joints
unchanged); its derivative enters the Jacobian's action by a difference of two contact solves
(the contact problem is piecewise linear in its load). The stop test is the out-of-balance force
``‖K u - f - p(u) + Bᵀ W t‖`` against the increment's load, at ``solver.tolerance`` (not finer
than :data:`MIN_TOLERANCE`).

Load stepping is automatic: an increment whose Newton iteration fails is split in halves (down to
1/2^:data:`MAX_SPLITS` of it) and the sub-increments grow again as they converge in a few steps
(:func:`_follow`). An increment that fails even then is a collapse of the ground (a limit load: no
equilibrium beyond it), reported with the largest deconfinement it held
(:class:`~solver.errors.GroundCollapseError`).

Stages (SPEC §1.1): stage 1 releases λd of the excavation load in ``solver.load_steps`` equal
increments on the unsupported ground (those below the first yield, :func:`.points.first_yield`,
in one elastic solve; each increment starts from the last one's displacement change, scaled to
its length); the yield state at its end is kept for the results (``stage1_plastic``); the lining
is placed on the ground as it stands; stage 2 releases the rest (with the lining's weight, the
water and a drained lining's seepage) in as many increments. The stress history lives at the
quadrature points (degree 4, six per triangle); the stored face stresses are followed, with the
same history, at the sub-triangle centroids.
"""
from __future__ import annotations

import logging

import numpy as np

from ..errors import GroundCollapseError
from ..results.post import mean_convergence
from .contact import contact_tractions
from .loads import stage_loads
from .newton import Stalled, solve_increment
from .points import Points, first_yield
from .recovery import finish
from .state import Forward, StageLoads

log = logging.getLogger(__name__)

#: The finest plastic equilibrium tolerance: ``solver.tolerance`` is honoured down to it (the
#: out-of-balance force relative to the increment's load; rounding in the force of a case at
#: 60k unknowns is about 1e-10 of it).
MIN_TOLERANCE = 1e-6
#: Newton's iteration that stalls below this fraction of the increment's load is finished by
#: active-set steps (:func:`.newton.solve_increment`); above it the increment is split.
ENDGAME = 5e-2
#: A failing increment is halved at most this many times (sub-increments of 1/256 of it).
MAX_SPLITS = 8
#: A sub-increment that converged in at most this many residual evaluations is followed by one
#: twice as long (else by one as long).
GROW_BELOW = 4


def plastic_tolerance(spec) -> float:
    """The plastic stop test's tolerance: ``solver.tolerance``, not finer than :data:`MIN_TOLERANCE`."""
    return max(spec.solver.tolerance, MIN_TOLERANCE)


def _follow(solve, commit, x, x_prev, h_prev: float, start: float, end: float, where: str, size: int):
    """Take the load from the fraction ``start`` to ``end`` (one increment): in one step, or,
    where Newton's iteration fails, in sub-increments halved until they converge (down to
    1/2^:data:`MAX_SPLITS` of the increment) and doubled again after each quick success.

    ``solve(frac, guess)`` is Newton's iteration at the load fraction ``frac``; ``commit`` stores
    a converged state. Each step starts from the last one's displacement change, scaled to its
    length; the first tries ``size`` (in 1/2^MAX_SPLITS of the increment). Returns the
    displacement, its state, the residual evaluations and Krylov steps spent (failed attempts
    included), the last step's start and length and the size the next increment tries first;
    raises :class:`GroundCollapseError` with the largest fraction held when even the smallest
    sub-increment fails."""
    units = 2**MAX_SPLITS
    pos, evaluations, krylov = 0, 0, 0
    state = None
    while pos < units:
        size = min(size, units - pos)
        h = (end - start) * size / units
        frac = end if pos + size == units else start + (end - start) * (pos + size) / units
        try:
            new, state, its, kry = solve(frac, x + (h / h_prev) * (x - x_prev))
        except Stalled as stall:
            evaluations += stall.iterations
            if size == 1:
                held = start + (end - start) * pos / units
                raise GroundCollapseError(where, held, frac, stall.force, stall.atol, stall.reason) from None
            size //= 2
            log.debug("%s: %s at %.3g N/m > %.3g; sub-increments of %d/%d", where, stall.reason, stall.force,
                      stall.atol, size, units)
            continue
        evaluations += its
        krylov += kry
        commit(state)
        x_prev, x, h_prev = x, new, h
        pos += size
        size *= 2 if its <= GROW_BELOW else 1
    return x, state, evaluations, krylov, x_prev, h_prev, min(size, units)


def _stage_one(model, rows, release, ld: float, steps: int, tol: float, gauss: Points, commit):
    """Stage 1: λd r on the unsupported ground in ``steps`` equal increments; those the ground
    takes elastically in one solve (up to its first yield). Returns the free-DOF displacement,
    the plastic load, the residual evaluations and Krylov steps and the ground reaction curve
    [(released, convergence)]."""
    ground = model.ground
    body, iface = ground.body, model.mesh.interface
    K = ground.stiffness()
    counts, curve = np.zeros(2, int), []
    u1, p1 = np.zeros(body.n), np.zeros(body.n)
    if release is None or ld <= 0:
        return u1, p1, counts, curve
    y_r = ground.forward(release, rows)
    u_r = ground.backward(y_r, rows)
    elastic = int(np.floor(first_yield(gauss, u_r, ld) / ld * steps * (1 + 1e-12)))
    if elastic:
        u1 = ld * elastic / steps * u_r
        commit((gauss.state(u1), None))
        reached = mean_convergence(body.expand(u1), iface)  # linear in the load up to here
        curve.extend((ld * k / steps, reached * k / elastic) for k in range(1, elastic + 1))
    u1_prev, h_prev = u1 - ld / steps * u_r, ld / steps
    atol = tol * ld / steps * float(np.linalg.norm(release))  # the increment's load

    def solve1(frac, guess):
        def residual(x, tangent, frozen=None):
            state = gauss.state(x, tangent, frozen)
            p = gauss.plastic_load(state.tau)
            F = x - ground.backward(frac * y_r + ground.forward(p, rows), rows)
            return F, float(np.linalg.norm(K @ F)), (state, p)

        def jacobian(at, F):
            soften = gauss.softening(at[0])
            return lambda v: v - ground.backward(ground.forward(soften(v), rows), rows)

        return solve_increment(residual, jacobian, lambda at: gauss.flowing(at[0]), guess, atol, ENDGAME * atol / tol)

    size = 2**MAX_SPLITS
    for k in range(elastic + 1, steps + 1):
        u1, at, its, kry, u1_prev, h_prev, size = _follow(
            solve1, commit, u1, u1_prev, h_prev, ld * (k - 1) / steps, ld * k / steps,
            f"stage 1, increment {k} of {steps}", size)
        p1 = at[1]
        counts += (its, kry)
        curve.append((ld * k / steps, mean_convergence(body.expand(u1), iface)))
    return u1, p1, counts, curve


def _stage_two(model, spec, rows, loads, steps: int, tol: float, atol: float, u1, p1, gauss: Points, commit):
    """Stage 2: the rest with the lining and contact, in ``steps`` increments. Returns the
    stage's displacement, its last plastic load and the residual evaluations and Krylov steps."""
    ground, lining = model.ground, model.lining
    K = ground.stiffness()
    full = StageLoads(loads.ground, loads.lining, None, loads.seepage)
    y_g, y_l = ground.forward(full.ground, rows), lining.forward(full.lining, rows)
    F2_full = model.mode_loads(full.lining)
    w = model.w

    def solve2(a, guess):
        def residual(x, tangent, frozen=None):
            state = gauss.state(u1 + x, tangent, frozen)
            p = gauss.plastic_load(state.tau)
            y = a * y_g + ground.forward(p - p1, rows)
            d = ground.jumps(y, rows) + lining.jumps(a * y_l, rows)
            t = contact_tractions(model, spec, d, a * F2_full)[1]
            F = x - ground.backward(y, rows, w * t)
            return F, float(np.linalg.norm(K @ F)), (state, p, d, t)

        def jacobian(at, F):
            state, _, d, t = at
            soften = gauss.softening(state)

            def apply(v):
                y = ground.forward(soften(v), rows)
                dd = ground.jumps(y, rows)
                size = float(np.linalg.norm(dd))
                dt = 0.0 * t
                if size > 0.0:  # the contact problem is piecewise linear in its load
                    h = 1e-6 * max(float(np.linalg.norm(d)), size) / size
                    dt = (contact_tractions(model, spec, d + h * dd, a * F2_full)[1] - t) / h
                return v - ground.backward(y, rows, w * dt)

            return apply

        return solve_increment(residual, jacobian, lambda at: gauss.flowing(at[0]), guess, atol,
                               ENDGAME * atol / tol)

    u2 = u2_prev = np.zeros(ground.body.n)
    h_prev, size, p, counts = 1.0 / steps, 2**MAX_SPLITS, p1, np.zeros(2, int)
    for k in range(1, steps + 1):
        u2, at, its, kry, u2_prev, h_prev, size = _follow(
            solve2, commit, u2, u2_prev, h_prev, (k - 1) / steps, k / steps, f"stage 2, increment {k} of {steps}",
            size)
        p = at[1]
        counts += (its, kry)
    return u2, p, counts


def _stage_two_load(loads, steps: int, F2, ref1: float) -> float:
    """The load of one stage-2 increment (N/m): the ground's and the lining's (on its rigid modes)
    share, not below a stage-1 increment's (a stage that releases little)."""
    return max((float(np.linalg.norm(loads.ground)) + float(np.sum(np.abs(F2)))) / steps, ref1)


def release_unsupported(model, spec, rows, fraction: float = 1.0):
    """Stage 1 alone: ``fraction`` of the excavation load released on the unsupported ground in
    ``solver.load_steps`` increments (as :func:`solve_staged` begins). Returns the ground reaction
    curve [(released, convergence)] and the quadrature points' history (:class:`Points`: where
    the ground yielded). Raises :class:`NotConvergedError` where the ground collapses."""
    gauss = Points(model, spec, "gauss")
    release = stage_loads(model, spec).release

    def commit(state):
        gauss.commit(state[0])

    curve = _stage_one(model, rows, release, fraction, spec.solver.load_steps, plastic_tolerance(spec), gauss,
                       commit)[3]
    return curve, gauss


def solve_staged(model, spec, rows, t0: float):
    """Solve a case whose ground can yield (see the module's docstring): a
    :class:`~solver.model.Solution` with ``plastic`` results filled."""
    ground = model.ground
    gauss = Points(model, spec, "gauss")
    out = Points(model, spec, "points")
    loads = stage_loads(model, spec)
    steps = spec.solver.load_steps
    tol = plastic_tolerance(spec)
    ld = spec.excavation.deconfinement if loads.release is not None else 0.0

    def commit(state):
        gauss.commit(state[0])
        out.commit(out.state(state[0].u))

    u1, p1, counts, curve = _stage_one(model, rows, loads.release, ld, steps, tol, gauss, commit)
    stage1 = out.at_yield.reshape(-1).copy()
    ref1 = ld / steps * float(np.linalg.norm(loads.release)) if loads.release is not None else 0.0
    full = StageLoads(loads.ground, loads.lining, None, loads.seepage)
    atol2 = tol * _stage_two_load(full, steps, model.mode_loads(full.lining), ref1)
    u2, p, counts2 = _stage_two(model, spec, rows, loads, steps, tol, atol2, u1, p1, gauss, commit)
    counts = counts + counts2
    # the whole contact stage (both bodies, the checks) of the last increment's converged iterate
    extra = p - p1
    stage = Forward(ground=ground.forward(full.ground + extra, rows), lining=model.lining.forward(full.lining, rows))
    jumps = ground.jumps(stage.ground, rows) + model.lining.jumps(stage.lining, rows)
    sol = finish(model, spec, rows, StageLoads(full.ground + extra, full.lining, None), stage, jumps,
                 model.mode_loads(full.lining), t0, u1=u1)
    sol.plastic = {
        "stress": out.sigma.reshape(4, -1),
        "at_yield": out.at_yield.reshape(-1),
        "stage1_at_yield": stage1,
        "eqps": out.eqps.reshape(-1),
        "iterations": int(counts[0]),
        "krylov": int(counts[1]),
        "ground_reaction": curve,
        "elements": out.shape[0],
    }
    return sol

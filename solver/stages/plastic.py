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
mapping (:mod:`solver.ground.mohr_coulomb`, :mod:`solver.ground.hoek_brown`).

Where a load step stalls (:data:`STAGNATION`) it is halved, and the steps grow again as they
converge (:func:`_advance`; the automatic step control of commercial codes). Where a stage-1 step
of 1/8 of its increment still stalls, the path has a local limit point: with flow far from
associated (ψ = 0 against φ = 25°) a shear band forming in the unsupported ground makes the load it
holds dip by a few per cent of an increment and rise again (a snap-through). Load control cannot
pass it; arc-length steps (Riks) follow the path through, the load solved from the arc's plane at
each iterate (``G`` is affine in the load, so the arc costs nothing per iteration). A path whose
load falls by more than half an increment below its peak has passed the ground's limit load: the
unsupported ground collapses, and the error says so with what it held. The consistent tangent is not
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
from ..limits import check_time
from ..results.post import mean_convergence
from .contact import contact_tractions
from .loads import stage_loads
from .mixing import Anderson
from .recovery import finish
from .state import Forward, StageLoads

log = logging.getLogger(__name__)

#: The least distance from the yield surface (relative) at which a point is reported at yield:
#: a tenth of ``solver.plastic_tolerance`` if coarser (the iteration leaves yielding points a hair inside).
FLAG_TOLERANCE = 1e-3
#: Iterations allowed per load increment: its steps (arc-length ones too) and their stalled attempts together.
MAX_STEP_ITERATIONS = 2500
#: An iteration has stalled when its least out-of-balance force has not fallen by a tenth in
#: this many iterations: the step is then halved, or followed by arc-length (:func:`_advance`); the
#: smallest steps have what is left of :data:`MAX_STEP_ITERATIONS`.
STAGNATION = 20
#: A step that converged in at most this many iterations is followed by one twice as long (else by
#: one as long; an arc-length step by one 1.6 times as long, or 0.6 times after a slow one).
GROW_BELOW = 15
#: A stalled stage-2 step is halved at most this many times (steps of 1/64 of the increment); the
#: arc-length steps likewise, from the first.
MAX_SPLITS = 6
#: A stage-1 step of 1/2^ARC_SPLITS of its increment that stalls is followed by arc-length steps.
ARC_SPLITS = 3
#: Anderson mixing depth.
DEPTH = 8


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


class _Stalled(Exception):
    """The iteration of one (sub-)increment stopped short of equilibrium: its last
    out-of-balance force and the iterations it took."""

    def __init__(self, force: float, atol: float, iterations: int):
        super().__init__(force, atol, iterations)
        self.force, self.atol, self.iterations = force, atol, iterations


def _fixed_point(G, x0: np.ndarray, K, atol: float, patience: int | None = STAGNATION,
                 limit: int = MAX_STEP_ITERATIONS, load=None):
    """Solve ``x = G(x)`` by constant-stiffness iterations with Anderson mixing, until the
    out-of-balance force ``‖K (G(x) - x)‖`` of an iterate ``x`` is at most ``atol``. ``G``
    returns the new iterate, the plastic load and the yield state at ``x``; the answer is that
    iterate with its plastic load, yield state (the state the stop test measured) and the
    iterations taken. Raises :class:`_Stalled` when the least force so far has not fallen by a
    tenth in ``patience`` iterations (if given), is not finite, or after ``limit`` iterations.

    ``load(p)``, if given, is the load ``G`` solved for (``K G(x) = load(p)`` with ``p`` the
    plastic load at ``x``): then ``K x`` is carried along Anderson's mix of those loads (one
    product with ``K`` at the start, none after), the force is ``‖load(p) - K x‖``, and the mix
    makes the least combination of these out-of-balance forces, not of the displacement changes
    ``G(x) - x = K⁻¹(load(p) - K x)``: as right-preconditioned GMRES minimizes the true residual, the
    mix then minimizes what the stop test measures (stage 1's iterations: issue 36's c 10 kPa,
    ψ 0 case 430 → 215, issue 25's weak ground 940 → 709; docs/performance.md). Without ``load``
    (stage 2, a contact solve in every ``G``) the mix keeps the displacement changes: its forces
    measured no better there."""
    acc = Anderson(DEPTH)
    x, force = x0, float("inf")
    mark, since = float("inf"), 0
    Kx = None if load is None else K @ x0
    for count in range(1, limit + 1):
        check_time("plastic iteration", count)
        gx, p, state = G(x)
        b = None if load is None else load(p)
        out_of_balance = K @ (gx - x) if b is None else b - Kx
        force = float(np.linalg.norm(out_of_balance))
        if force <= atol:
            return x, p, state, count
        if not np.isfinite(force):
            break
        if force < 0.9 * mark:
            mark, since = force, 0
        else:
            since += 1
            if patience is not None and since >= patience:
                break
        if b is None:
            x = acc.step(x, gx)
        else:
            x, Kx = acc.step(x, gx, b, out_of_balance)
    raise _Stalled(force, atol, count)


def _advance(solve, commit, x: np.ndarray, x_prev: np.ndarray, lam: float, lam_prev: float, end: float,
             increment: float, h: float, where: str, arc_length: bool = True):
    """Take a stage's load from ``lam`` to ``end`` (one increment, of ``increment``) along the
    equilibrium path: in load-controlled steps of ``h``, halved where the iteration stalls and
    doubled after a quick success (:data:`GROW_BELOW`); where a step of 1/2^:data:`ARC_SPLITS` of the
    increment still stalls (stage 1, ``arc_length``), by arc-length steps (Riks' plane normal to the
    last step; the load follows from the plane) until the end is within a step's reach.

    Why the arc: with flow far from associated, the discrete path of the unsupported ground has
    local limit points (snap-throughs): where a shear band forms, the released load the ground holds
    dips by a few per cent of an increment and rises again. Issue 36's sample: each increment that
    stalled in load control down to 1/64 of it was one. Load control cannot pass them; the arc-length
    steps follow the path through. A path whose load falls below its peak by more than half an
    increment has passed the ground's limit load: the ground collapses, and the error says what it
    held (:class:`~solver.errors.GroundCollapseError`). Without ``arc_length`` (stage 2: the contact
    makes the load's share of each iterate nonlinear) the halving goes on to 1/2^:data:`MAX_SPLITS`.
    The smallest steps (load control there, arc-length steps 1/2^MAX_SPLITS of the first) run
    without the stall test, on what is left of :data:`MAX_STEP_ITERATIONS`.

    ``solve(guess, limit, patience, frac=…)`` is the equilibrium iteration (:func:`_fixed_point`,
    plus the load reached) at the load ``frac``; for stage 1 also ``solve(…, arc=(x_s, n, ds))``.
    ``commit`` stores a converged state. Each step starts from the last one's displacement change,
    scaled to its load. Returns the displacement, the plastic load, the iterations spent (stalled
    attempts included), the last step's start and load and the step the next increment tries first."""
    used, p, arc = 0, None, None  # arc: the arc-length step once load control has stalled
    peak, least = lam, 0.0  # least: the arc step below which an attempt runs without a stall test
    parked, tried = None, None  # the arc step set aside while load control tries the end; where it failed
    smallest = increment / 2**(ARC_SPLITS if arc_length else MAX_SPLITS)
    while lam < end:
        left = MAX_STEP_ITERATIONS - used
        if left <= 0:
            raise NotConvergedError(
                f"solver.load_steps: the yielding ground did not reach equilibrium in {where}: its "
                f"{MAX_STEP_ITERATIONS} iterations ran out at {lam:.4g} of {end:.4g} of the load, in steps down "
                f"to {min(h, end - lam) / increment:.2g} of the increment{'' if arc is None else ' (arc-length)'} "
                "(a stronger ground, or a coarser solver.plastic_tolerance)")
        step = x - x_prev
        length = float(np.linalg.norm(step))
        if arc is not None and lam != tried and lam > lam_prev and lam + (lam - lam_prev) / length * arc >= end:
            arc, parked, h = None, arc, end - lam  # the end within the arc's reach: load control to it
        try:
            if arc is None:
                target = end if lam + h >= end - 1e-9 * increment else lam + h
                guess = x + ((target - lam) / (lam - lam_prev)) * step if lam > lam_prev else x
                patience = None if not arc_length and h <= smallest * (1 + 1e-9) else STAGNATION
                new, p_new, state, its, lam_new = solve(guess, left, patience, frac=target)
            else:
                n = step / length
                new, p_new, state, its, lam_new = solve(x + arc * n, left, STAGNATION if arc > least else None,
                                                        arc=(x, n, arc))
        except _Stalled as stall:
            used += stall.iterations
            if arc is None and parked is not None:  # load control to the end stalled: on along the arc
                arc, parked, tried = 0.5 * parked, None, lam
            elif arc is None and h > smallest * (1 + 1e-9):
                h /= 2
            elif arc is None and arc_length and lam > lam_prev:
                arc = length * min(1.0, h / (lam - lam_prev))
                least = arc / 2**MAX_SPLITS
            elif arc is not None and arc > least:
                arc *= 0.5
            else:
                raise NotConvergedError(
                    f"solver.load_steps: the yielding ground did not reach equilibrium in {where} (out-of-balance "
                    f"force {stall.force:.3g} N/m > {stall.atol:.3g} after {used} iterations, at {lam:.4g} of "
                    f"{end:.4g} of the load, in steps down to 1/{round(increment / h)} of the increment"
                    f"{'' if arc is None else ' and arc-length steps down to 1/64 of the first'}): a coarser "
                    "solver.plastic_tolerance, or a dilatancy closer to the friction angle") from None
            log.debug("%s: stalled at %.3g N/m > %.3g after %d iterations; %s", where, stall.force, stall.atol,
                      stall.iterations, f"steps of {h / increment:.3g} of the increment" if arc is None
                      else f"arc-length steps of {arc:.3g}")
            continue
        used += its
        if lam_new > end:  # the arc went past the increment's end: a shorter one
            arc *= 0.5 * (end - lam) / (lam_new - lam)
            continue
        if arc is not None and lam_new < lam and p is not None and np.array_equal(p_new, p):
            # no point flows: the arc has turned back down the elastic unloading line, not along the path
            raise NotConvergedError(
                f"solver.load_steps: the yielding ground did not reach equilibrium in {where}: past a limit point "
                f"at λ {peak:.4g} (of {end:.4g}) the arc-length path turned back into elastic unloading after "
                f"{used} iterations (a coarser solver.plastic_tolerance, more solver.load_steps, or a dilatancy "
                "closer to the friction angle)")
        commit(*state)
        x_prev, lam_prev, x, lam, p = x, lam, new, float(lam_new), p_new
        peak = max(peak, lam)
        if peak - lam > 0.5 * increment:
            raise GroundCollapseError(
                f"excavation.deconfinement: the unsupported ground collapses in {where}: the load it holds "
                f"peaks at λ {peak:.4g} and falls to {lam:.4g} as it deforms further (a stronger ground, or "
                "support placed earlier: a lower excavation.deconfinement)")
        if arc is not None:
            arc *= 1.6 if its <= GROW_BELOW else (1.0 if its <= 2 * STAGNATION else 0.6)
        elif its <= GROW_BELOW:
            h *= 2
    return x, p, used, x_prev, lam_prev, min(h, increment)


def _stage_one(model, rows, release, ld: float, steps: int, tol: float, gauss: "_Points", stress_of, commit):
    """Stage 1: λd r on the unsupported ground in ``steps`` equal increments; those the ground
    takes elastically in one solve (up to its first yield). Returns the free-DOF displacement,
    the plastic load, the iterations and the ground reaction curve [(released, convergence)]."""
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
            commit(*stress_of(u1))
            reached = mean_convergence(body.expand(u1), iface)  # linear in the load up to here
            curve.extend((ld * k / steps, reached * k / elastic) for k in range(1, elastic + 1))
        u1_prev = u1 - ld / steps * u_r

        atol = tol * ld / steps * float(np.linalg.norm(release))  # of the increment's load (SPEC §9.1)

        unit = mean_convergence(body.expand(u_r), iface)  # the elastic ground's, of the whole release

        def solve1(guess, limit, patience, frac=None, arc=None):
            """Equilibrium at the load ``frac`` (load control) or, with ``arc`` = (x_s, n, ds), on the
            plane ``n·(x - x_s) = ds`` at the load that plane asks of each iterate (arc-length: the
            load is affine in it, ``G(x) = K⁺p(x) + λ(x) u_r``). Returns the :func:`_fixed_point`
            answer and its load."""
            box = {}

            def G(x):
                state = stress_of(x)
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
            return _fixed_point(G, guess, K, atol, patience, limit, load) + (box["lam"],)

        lam, lam_prev, h = ld * elastic / steps, ld * (elastic - 1) / steps, ld / steps
        for k in range(elastic + 1, steps + 1):
            where = f"stage 1, increment {k} of {steps}"
            try:
                u1, p1, its, u1_prev, lam_prev, h = _advance(solve1, commit, u1, u1_prev, lam, lam_prev,
                                                             ld * k / steps, ld / steps, h, where)
            except NotConvergedError as err:
                raise type(err)(f"{err}. {held(curve, unit)}") from None
            lam = ld * k / steps
            iterations += its
            curve.append((lam, mean_convergence(body.expand(u1), iface)))
    return u1, p1, iterations, curve


def held(curve: list[tuple[float, float]], unit: float) -> str:
    """What the unsupported ground held before a stage-1 increment failed, for the failure's
    message: the last converged release on the ground reaction ``curve`` [(released, mean
    convergence)], its convergence against the elastic ground's (``unit``: the elastic mean
    convergence of the whole excavation load) and how steep the curve had become. Near a
    mechanism the curve steepens without bound (the last increment many times as steep as the
    elastic line); a stall with the curve still near elastic is the iteration's, not the ground's."""
    if not curve or unit == 0:
        return "The ground yielded within the first increment: no release converged on the unsupported ground"
    (l0, c0), (l1, c1) = ((0.0, 0.0), curve[-1]) if len(curve) == 1 else curve[-2:]
    return (f"The unsupported ground held λd {l1:.3g} (mean wall convergence {1e3 * c1:.3g} mm, "
            f"{c1 / (l1 * unit):.3g} times the elastic ground's; the ground reaction curve's last "
            f"increment {(c1 - c0) / ((l1 - l0) * unit):.3g} times as steep as the elastic line)")


def release_unsupported(model, spec, rows, fraction: float = 1.0):
    """Stage 1 alone: ``fraction`` of the excavation load released on the unsupported ground in
    ``solver.load_steps`` increments (as :func:`solve_staged` begins). Returns the ground reaction
    curve [(released, convergence)] and the quadrature points' history (:class:`_Points`: where
    the ground yielded). Raises :class:`NotConvergedError` where the ground collapses."""
    gauss = _Points(model, spec, "gauss")
    release = stage_loads(model, spec).release
    tol = spec.solver.plastic_tolerance

    def stress_of(u_free):
        grad = gauss.gradient(u_free)
        return (u_free, grad) + gauss.trial(grad)

    def commit(u_free, grad, stress, dep, flags, tau):
        gauss.commit(grad, stress, dep, flags, tau)

    curve = _stage_one(model, rows, release, fraction, spec.solver.load_steps, tol, gauss, stress_of, commit)[3]
    return curve, gauss


def solve_staged(model, spec, rows, t0: float):
    """Solve a case whose ground can yield (see the module's docstring): a
    :class:`~solver.model.Solution` with ``plastic`` results filled."""
    ground, lining = model.ground, model.lining
    body = ground.body
    gauss = _Points(model, spec, "gauss")
    out = _Points(model, spec, "points")
    loads = stage_loads(model, spec)
    steps = spec.solver.load_steps
    tol = spec.solver.plastic_tolerance
    ld = spec.excavation.deconfinement if loads.release is not None else 0.0
    K = ground.stiffness()

    def stress_of(u_free):
        grad = gauss.gradient(u_free)
        return (u_free, grad) + gauss.trial(grad)

    def commit(u_free, grad, stress, dep, flags, tau):
        gauss.commit(grad, stress, dep, flags, tau)
        og = out.gradient(u_free)
        out.commit(og, *out.trial(og))

    u1, p1, iterations, curve = _stage_one(model, rows, loads.release, ld, steps, tol, gauss, stress_of, commit)
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

    def solve2(guess, limit, patience, frac):

        def G(x):
            state = stress_of(u1 + x)
            p = _plastic_load(gauss, state[-1])
            _, stage, d = stage_of(p, frac)
            _, t = contact_tractions(model, spec, d, frac * F2_full)
            return ground.backward(stage.ground, rows, model.w * t), p, state

        return _fixed_point(G, guess, K, atol, patience, limit) + (frac,)

    a, a_prev, h = 0.0, -1.0 / steps, 1.0 / steps
    for k in range(1, steps + 1):
        u2, p, its, u2_prev, a_prev, h = _advance(solve2, commit, u2, u2_prev, a, a_prev, k / steps, 1.0 / steps, h,
                                                  f"stage 2, increment {k} of {steps}", arc_length=False)
        a = k / steps
        iterations += its
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

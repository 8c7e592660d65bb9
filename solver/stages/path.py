"""The equilibrium path of the staged plastic solve (:mod:`solver.stages.plastic`): the iteration that
finds one equilibrium (:func:`fixed_point`: constant stiffness, Anderson mixing) and the step control
that strings equilibria along a stage's load (:func:`advance`): load steps halved where the iteration
stalls and grown again as it converges, and in stage 1 arc-length steps past the path's snap-throughs.
"""
from __future__ import annotations

import logging

import numpy as np

from ..errors import GroundCollapseError, NotConvergedError
from ..limits import check_time
from .mixing import Anderson

log = logging.getLogger(__name__)

#: Iterations allowed per load increment, on average over a stage: its steps (arc-length ones too) and their
#: stalled attempts together. A stage's increments share this many times their number (:func:`share`), so
#: an increment that needs more takes what the easier ones left.
MAX_STEP_ITERATIONS = 2500
#: No increment takes more than this many times :data:`MAX_STEP_ITERATIONS` (:func:`share`): what a case
#: that fails spends stays bounded. (Four: issue 36's c 10 kPa ground released to λd 0.8 takes 5 234
#: iterations in its last increment, near the ground's limit, and converges.)
MOST_SHARES = 4
#: An iteration has stalled when its least out-of-balance force has not fallen by a tenth in
#: this many iterations: the step is then halved, or followed by arc-length (:func:`advance`); the
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
#: Along the arc, a doubling of the displacement that gains less than this share of an increment's load
#: is a mechanism: the unsupported ground collapses (:func:`advance`).
PLATEAU = 0.01
#: What a collapse's message advises.
ADVICE = "a stronger ground, or support placed earlier: a lower excavation.deconfinement"
#: Anderson mixing depth.
DEPTH = 8


def share(increment: int, used: int) -> int:
    """The iterations left to a stage's ``increment``-th increment (counted from its first plastic one)
    after ``used`` in those before: :data:`MAX_STEP_ITERATIONS` an increment, with what the easier
    ones left, and at most :data:`MOST_SHARES` of them (:func:`advance`'s ``budget``)."""
    return min(MAX_STEP_ITERATIONS * increment - used, MOST_SHARES * MAX_STEP_ITERATIONS)


class Stalled(Exception):
    """The iteration of one step stopped short of equilibrium: its last out-of-balance force, the
    force asked and the iterations it took."""

    def __init__(self, force: float, atol: float, iterations: int):
        super().__init__(force, atol, iterations)
        self.force, self.atol, self.iterations = force, atol, iterations


def fixed_point(G, x0: np.ndarray, K, atol: float, patience: int | None = STAGNATION,
                limit: int = MAX_STEP_ITERATIONS, load=None, carried: np.ndarray | None = None):
    """Solve ``x = G(x)`` by constant-stiffness iterations with Anderson mixing, until the
    out-of-balance force ``‖K (G(x) - x)‖`` of an iterate ``x`` is at most ``atol``. ``G``
    returns the new iterate, the plastic load and the yield state at ``x``; the answer is that
    iterate with its plastic load, yield state (the state the stop test measured) and the
    iterations taken. Raises :class:`Stalled` when the least force so far has not fallen by a
    tenth in ``patience`` iterations (if given), is not finite, or after ``limit`` iterations.

    ``load(p)``, if given, is the load ``G`` solved for (``K G(x) = load(p)`` with ``p`` the
    plastic load at ``x``): then ``K x`` is carried along Anderson's mix of those loads (one
    product with ``K`` at the start, or ``carried``, that product given: ``K`` is then not used), the
    force is ``‖load(p) - K x‖``, and the mix makes the least combination of these out-of-balance
    forces, not of the displacement changes
    ``G(x) - x = K⁻¹(load(p) - K x)``: as right-preconditioned GMRES minimizes the true residual, the
    mix then minimizes what the stop test measures (stage 1's iterations: issue 36's c 10 kPa,
    ψ 0 case 430 → 215, issue 25's weak ground 940 → 709; docs/performance.md). Without ``load``
    (stage 2 on the whole ground, a contact solve in every ``G``) the mix keeps the displacement changes: its forces
    measured no better there; on its yielding zone stage 2 carries its loads, their forward solves
    the iterate: :class:`solver.stages.plastic._ContactReach`)."""
    if limit < 1:
        raise Stalled(float("inf"), atol, 0)
    acc = Anderson(DEPTH)
    x, force = x0, float("inf")
    mark, since = float("inf"), 0
    Kx = None if load is None else (K @ x0 if carried is None else carried)
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
    raise Stalled(force, atol, count)


class _Steps:
    """The step control of one increment (:func:`advance`): the load step ``h``; once load control
    has stalled at the smallest step (stage 1), the arc-length step ``arc``."""

    def __init__(self, increment: float, h: float, arc_length: bool):
        self.increment, self.h, self.arc_length = increment, h, arc_length
        self.smallest = increment / 2**(ARC_SPLITS if arc_length else MAX_SPLITS)
        self.arc = None
        self.least = 0.0  # the arc step at and below which an attempt runs without a stall test
        self.parked = None  # the arc step set aside while load control tries the increment's end
        self.tried = None  # the load where that try stalled (the arc goes on from there)

    def aim(self, lam: float, lam_prev: float, length: float, end: float) -> None:
        """With the end of the increment within the arc's reach (the path rising), load control to it."""
        if self.arc is not None and lam != self.tried and lam > lam_prev \
                and lam + (lam - lam_prev) / length * self.arc >= end:
            self.arc, self.parked, self.h = None, self.arc, end - lam

    def take(self, solve, x, step, length: float, lam: float, lam_prev: float, end: float, left: int):
        """One step's equilibrium, from the last step's displacement change scaled to this one."""
        if self.arc is None:
            target = end if lam + self.h >= end - 1e-9 * self.increment else lam + self.h
            guess = x + ((target - lam) / (lam - lam_prev)) * step if lam > lam_prev else x
            last = not self.arc_length and self.h <= self.smallest * (1 + 1e-9)
            return solve(guess, left, None if last else STAGNATION, frac=target)
        n = step / length
        return solve(x + self.arc * n, left, STAGNATION if self.arc > self.least else None, arc=(x, n, self.arc))

    def stalled(self, lam: float, lam_prev: float, length: float) -> bool:
        """The next, shorter step after a stall; False when there is none."""
        if self.arc is None and self.parked is not None:  # load control to the end stalled: on along the arc
            self.arc, self.parked, self.tried = 0.5 * self.parked, None, lam
        elif self.arc is None and self.h > self.smallest * (1 + 1e-9):
            self.h /= 2
        elif self.arc is None and self.arc_length and lam > lam_prev:
            self.arc = length * min(1.0, self.h / (lam - lam_prev))
            self.least = self.arc / 2**MAX_SPLITS
        elif self.arc is not None and self.arc > self.least:
            self.arc *= 0.5
        else:
            return False
        return True

    def converged(self, iterations: int) -> None:
        if self.arc is not None:
            self.arc *= 1.6 if iterations <= GROW_BELOW else (1.0 if iterations <= 2 * STAGNATION else 0.6)
        elif iterations <= GROW_BELOW:
            self.h *= 2

    def __str__(self) -> str:
        return (f"steps of {self.h / self.increment:.3g} of the increment" if self.arc is None
                else f"arc-length steps of {self.arc:.3g}")


def _collapse(where: str, x: np.ndarray, lam: float, peak: float, ref, increment: float):
    """Raise :class:`~solver.errors.GroundCollapseError` where the path has passed the ground's limit
    load (its load ``lam`` more than half an increment below its ``peak``) or reached it (since ``ref``,
    the displacement and load where the arc began or last doubled, the displacement has doubled for
    less than :data:`PLATEAU` of an increment's load, the path at its peak); else the reference for the
    next doubling (in a dip below the peak, the dip's latest state)."""
    advice = ADVICE  # (short: it fills two messages)
    if peak - lam > 0.5 * increment:
        raise GroundCollapseError(
            f"excavation.deconfinement: the unsupported ground collapses in {where}: the load it holds peaks at "
            f"λ {peak:.4g} and falls to {lam:.4g} as it deforms further ({advice})", peak)
    if ref is not None and lam < peak - PLATEAU * increment:
        return x, lam  # in a dip below the peak (a snap-through): a plateau is measured from where it ends
    if ref is None or np.linalg.norm(x - ref[0]) < np.linalg.norm(ref[0]):
        return ref
    if lam - ref[1] < PLATEAU * increment:
        raise GroundCollapseError(
            f"excavation.deconfinement: the unsupported ground collapses in {where}: its ground reaction levels out "
            f"at λ {peak:.4g}, the displacement doubling for {lam - ref[1]:.2g} more of the load (less than "
            f"{PLATEAU:.0%} of an increment; {advice})", peak)
    return x, lam


def advance(solve, commit, x: np.ndarray, x_prev: np.ndarray, lam: float, lam_prev: float, end: float,
            increment: float, h: float, where: str, arc_length: bool = True, budget: int | None = None):
    """Take a stage's load from ``lam`` to ``end`` (one increment, of ``increment``) along the
    equilibrium path: in load-controlled steps of ``h``, halved where the iteration stalls and
    doubled after a quick success (:data:`GROW_BELOW`); where a step of 1/2^:data:`ARC_SPLITS` of the
    increment still stalls (stage 1, ``arc_length``), by arc-length steps (Riks' plane normal to the
    last step; the load follows from the plane) until the end is within a step's reach.

    Why the arc: with flow far from associated, the discrete path of the unsupported ground has
    local limit points (snap-throughs): where a shear band forms, the released load the ground holds
    dips by a few per cent of an increment and rises again. Issue 36's sample: the increments that
    stalled in load control down to 1/64 of them were such. Load control cannot pass them; the
    arc-length steps follow the path through. A path whose load falls below its peak by more than
    half an increment while the ground flows has passed the ground's limit load, and one whose
    displacement doubles for less than :data:`PLATEAU` of an increment's load has reached it (a
    mechanism): the ground collapses, and the error says what it held
    (:class:`~solver.errors.GroundCollapseError`). An arc
    step down the elastic unloading line (the load falling, no point flowing) is no path: refused.
    Without ``arc_length`` (stage 2: the contact makes the load's share of an iterate nonlinear) the
    halving goes on to 1/2^:data:`MAX_SPLITS`. The smallest steps run without the stall test, on what
    is left of the increment's ``budget`` of iterations (what its stage has left; default
    :data:`MAX_STEP_ITERATIONS`).

    ``solve(guess, limit, patience, frac=…)`` is the equilibrium iteration (:func:`fixed_point`, plus
    the load reached) at the load ``frac``; for stage 1 also ``solve(…, arc=(x_s, n, ds))``. ``commit``
    stores a converged state. Returns the displacement, the plastic load, the iterations spent
    (stalled attempts included), the last step's start and load and the step the next increment
    tries first."""
    budget = MAX_STEP_ITERATIONS if budget is None else budget
    steps = _Steps(increment, h, arc_length)
    used, p, peak, ref = 0, None, lam, None
    while lam < end:
        left = budget - used
        if left <= 0:
            raise NotConvergedError(
                f"solver.load_steps: the yielding ground did not reach equilibrium in {where}: its "
                f"{budget} iterations ran out at {lam:.4g} of {end:.4g} of the load, in {steps} "
                "(a stronger ground, or a coarser solver.plastic_tolerance)")
        step = x - x_prev
        length = float(np.linalg.norm(step))
        steps.aim(lam, lam_prev, length, end)
        try:
            new, p_new, state, its, lam_new = steps.take(solve, x, step, length, lam, lam_prev, end, left)
        except Stalled as stall:
            used += stall.iterations
            if not steps.stalled(lam, lam_prev, length):
                raise NotConvergedError(
                    f"solver.load_steps: the yielding ground did not reach equilibrium in {where} (out-of-balance "
                    f"force {stall.force:.3g} N/m > {stall.atol:.3g} after {used} iterations, at {lam:.4g} of "
                    f"{end:.4g} of the load, in {steps}): a coarser solver.plastic_tolerance, or a dilatancy "
                    "closer to the friction angle") from None
            log.debug("%s: stalled at %.3g N/m > %.3g after %d iterations; %s", where, stall.force, stall.atol,
                      stall.iterations, steps)
            continue
        used += its
        if lam_new > end:  # the arc went past the increment's end: a shorter one
            steps.arc *= 0.5 * (end - lam) / (lam_new - lam)
            continue
        if steps.arc is not None and lam_new < lam and p is not None and np.array_equal(p_new, p):
            raise NotConvergedError(
                f"solver.load_steps: the yielding ground did not reach equilibrium in {where}: past a limit point "
                f"at λ {peak:.4g} (of {end:.4g}) the arc-length path turned back into elastic unloading after "
                f"{used} iterations (a coarser solver.plastic_tolerance, more solver.load_steps, or a dilatancy "
                "closer to the friction angle)")
        commit(*state)
        log.debug("%s: at %.5g of the load after %d iterations (%s)", where, lam_new, its, steps)
        if steps.arc is not None and ref is None:
            ref = x, lam  # where the arc began: the displacement and load a plateau is measured from
        x_prev, lam_prev, x, lam, p = x, lam, new, float(lam_new), p_new
        peak = max(peak, lam)
        ref = _collapse(where, x, lam, peak, ref, increment)
        steps.converged(its)
    return x, p, used, x_prev, lam_prev, min(steps.h, increment)

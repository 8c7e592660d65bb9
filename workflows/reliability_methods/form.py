"""FORM: the design point by the improved HL-RF algorithm, then the probability by importance
sampling around it.

The design point u* is the point of the limit-state surface g(u) = 0 nearest the origin of the
standard normal space; β = |u*| (negative when the mean point fails) and α = u*/β its direction
cosines, α² the importance factors. HL-RF (Hasofer & Lind 1974, Rackwitz & Fiessler 1978)
steps to the zero of g's linearization nearest the origin; the improved HL-RF (Zhang & Der
Kiureghian 1995) shortens the step until the merit function ½|u|² + c|g| decreases, which
keeps it from cycling on a curved limit state. Gradients by forward differences: the point and
its d neighbours are one batch of cases (solved side by side, on one built model where the
variables leave the mesh and materials alone).

FORM's Φ(−β) is exact only for a limit state linear in u. The probability reported is the
importance-sampling estimate with the density N(u*, I) (Melchers 1989; OpenTURNS'
``PostAnalyticalImportanceSampling``): unbiased whatever the curvature, with its 95 % interval,
drawn in batches until its coefficient of variation reaches the target or the budget ends.
"""
from __future__ import annotations

import logging
import math
from typing import Callable, Optional

import numpy as np
from scipy import stats

from .limit_state import BudgetExhausted, LimitState
from .result import ReliabilityResult

logger = logging.getLogger(__name__)

#: Forward-difference step in the standard space (standard deviations): large enough that a
#: plastic solve's residual noise (1e-5 of the output) does not turn the gradient.
STEP = 5e-2
#: Convergence: |g| / |g(0)| within TOLERANCE, and either the distance of u* from the line of
#: its gradient over |u| within ALIGNMENT (an angle: β errs by its square, 5e-5 at 1e-2) or β
#: settled to TOLERANCE between iterations (FE outputs with kinks, the max over stations, or a
#: plastic solve's tolerance may keep the gradient from settling closer).
TOLERANCE = 1e-3
ALIGNMENT = 1e-2
MAX_ITERATIONS = 30
#: Importance sampling: batch size, fewest samples, target coefficient of variation.
IS_BATCH = 50
IS_MIN = 100
IS_COV = 0.05


def design_point(g: LimitState, *, step: float = STEP, tolerance: float = TOLERANCE,
                 alignment: float = ALIGNMENT, max_iterations: int = MAX_ITERATIONS, reserve: int = 0,
                 on_progress: Optional[Callable[[dict], None]] = None) -> dict:
    """iHL-RF from the origin: ``{"u", "g", "gradient", "converged", "iterations", "history"}``;
    stops short (not converged) when fewer than ``reserve`` calls would be left."""
    d = g.dimension
    u = np.zeros(d)
    scale, g0, history = None, None, []
    gu = grad = None
    converged = False
    iterations = 0
    for iterations in range(1, max_iterations + 1):
        if g.remaining - (d + 1) < reserve:
            break
        G = g(np.vstack([u, u + step * np.eye(d)]))
        gu, grad = G[0], (G[1:] - G[0]) / step
        if scale is None:
            g0, scale = float(gu), (abs(gu) if gu != 0 else 1.0)
        norm = float(np.linalg.norm(grad))
        if norm == 0.0:
            raise ValueError("the output does not change with the variables at the mean point (zero gradient)")
        beta = float(np.linalg.norm(u))
        history.append({"calls": g.calls, "beta": beta, "g": float(gu),
                        "stage": f"design point, iteration {iterations}"})
        if on_progress:
            on_progress(history[-1])
        alpha = grad / norm
        off_line = float(np.linalg.norm(u - (u @ alpha) * alpha))
        on_surface = abs(gu) <= tolerance * scale
        settled = len(history) > 1 and abs(beta - history[-2]["beta"]) <= tolerance * max(beta, 1.0)
        if on_surface and (off_line <= alignment * max(beta, 1.0) or settled):
            converged = True
            break
        direction = ((grad @ u - gu) / norm ** 2) * grad - u
        c = (2.0 * beta + 1.0) / norm  # > |u| / |∇g|: the merit function decreases along the step
        merit = 0.5 * u @ u + c * abs(gu)
        slope = u @ direction + c * math.copysign(1.0, gu) * (grad @ direction)
        lam, new = 1.0, u + direction
        for _ in range(6):
            if g.remaining - 1 < reserve:
                break
            new = u + lam * direction
            gn = float(g(new[None])[0])
            if 0.5 * new @ new + c * abs(gn) <= merit + 0.5 * lam * min(slope, 0.0):
                break
            lam *= 0.5
        u = new
    return {"u": u, "g": None if gu is None else float(gu), "g0": g0, "gradient": grad, "converged": converged,
            "iterations": iterations, "history": history}


def importance_sampling(g: LimitState, center: np.ndarray, *, seed: int, batch: int = IS_BATCH,
                        minimum: int = IS_MIN, target_cov: float = IS_COV,
                        on_progress: Optional[Callable[[dict], None]] = None) -> dict:
    """P(g < 0) by sampling N(center, I): ``{"probability", "ci_low", "ci_high", "cov", "samples", "history"}``."""
    rng = np.random.default_rng([seed, 1])
    d = g.dimension
    terms: list[np.ndarray] = []
    history = []
    p = se = float("nan")
    while True:
        Z = rng.standard_normal((batch, d))  # the full batch drawn always: the same stream on a resume
        take = min(batch, g.remaining)
        if take < 1:
            break
        U = center + Z[:take]
        try:
            G = g(U)
        except BudgetExhausted:  # cases seen before count once: fewer may fit than remaining says
            break
        w = np.exp(-U @ center + 0.5 * center @ center)  # φ(u) / φ(u − u*)
        terms.append(np.where(G < 0, w, 0.0))
        t = np.concatenate(terms)
        n = t.size
        p = float(t.mean())
        se = float(t.std(ddof=1) / math.sqrt(n)) if n > 1 else float("inf")
        cov = se / p if p > 0 else float("inf")
        history.append({"calls": g.calls, "probability": p, "ci_low": max(p - 1.96 * se, 0.0),
                        "ci_high": min(p + 1.96 * se, 1.0), "stage": "importance sampling"})
        if on_progress:
            on_progress(history[-1])
        if n >= minimum and cov <= target_cov:
            break
    n = int(sum(t.size for t in terms))
    if n == 0:
        return {"probability": float("nan"), "ci_low": float("nan"), "ci_high": float("nan"),
                "cov": None, "samples": 0, "history": history}
    return {"probability": p, "ci_low": max(p - 1.96 * se, 0.0), "ci_high": min(p + 1.96 * se, 1.0),
            "cov": se / p if p > 0 else None, "samples": n, "history": history}


def form(g: LimitState, *, seed: int = 0, on_progress: Optional[Callable[[dict], None]] = None,
         **options) -> ReliabilityResult:
    """FORM with its importance-sampling check (see the module's notes). A quarter of the
    budget is kept for the check while the design point is sought; the check takes the rest
    (it stops earlier at a c.o.v. of 5 %)."""
    found = design_point(g, reserve=g.budget // 4, on_progress=on_progress, **options)
    u = found["u"]
    beta = float(np.linalg.norm(u))
    if found["g0"] is not None and found["g0"] < 0:
        beta = -beta  # the mean point fails
    sampled = importance_sampling(g, u, seed=seed, on_progress=on_progress)
    note = None if found["converged"] else (
        f"the design point search did not converge in {found['iterations']} iterations within the budget")
    if sampled["samples"] == 0:
        note = (note + "; " if note else "") + "no budget left for the importance-sampling check"
    elif sampled["probability"] == 0.0:
        note = ((note + "; " if note else "")
                + "no importance sample failed: the probability is below what the sample sees")
    history = found["history"] + sampled["history"]
    return ReliabilityResult(
        method="form", probability=sampled["probability"], ci_low=sampled["ci_low"], ci_high=sampled["ci_high"],
        beta=beta, cov=sampled["cov"], design_point=u, calls=g.calls, converged=found["converged"],
        history=history, note=note,
        details={"form_probability": float(stats.norm.cdf(-beta)), "iterations": found["iterations"],
                 "design_point_g": found["g"], "importance_samples": sampled["samples"]})

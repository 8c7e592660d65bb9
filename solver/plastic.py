"""Yielding ground through the construction stages (SPEC §1.5): the staged, incremental solve.

Method: the constant-stiffness ("initial stress") iteration on the model's factorized elastic
stiffness, accelerated by Anderson mixing (:class:`_Anderson`). With ``ε_p`` the plastic
strain, the ground's equilibrium ``∫Bᵀ(σ - σ0′) = f`` reads ``K u = f + p(u)`` with the
plastic load ``p = ∫Bᵀ(σ0′ + D ε(u) - σ(u))``, non-zero only where the ground yields. Each
iteration solves the *elastic* problem with the load ``f + p``: one forward and one backward
triangular solve on the factors the model already holds and, in stage 2, the contact problem on
the same interface flexibility (so the bolt search, every interface model, water and layers
work unchanged). A sweep over loads, K0, λd or strength therefore still shares one model per
geometry. The stop test is the equilibrium residual: the out-of-balance force
``‖K u - f - p(u)‖`` of the iterate, relative to the increment's load, at most ``solver.tolerance``
floored at :data:`MIN_TOLERANCE`; the plastic consistency holds at every point by the return
mapping (:mod:`solver.mohr_coulomb`).

Stages (SPEC §1.1): stage 1 releases λd of the excavation load in ``solver.load_steps``
increments on the unsupported ground; the lining is placed on the ground as it stands; stage 2
releases the rest (with the lining's weight, the water and a drained lining's seepage) in as
many increments, each with its contact solve. The stress history lives at the quadrature
points (degree 4, six per triangle); the stored face stresses are followed, with the same
history, at the sub-triangle centroids.
"""
from __future__ import annotations

import numpy as np

from .assembly import _stress_components, point_basis
from .contact import NotConvergedError
from .limits import check_time
from .ground import in_situ_stress, moduli
from .mohr_coulomb import equivalent, return_map
from .post import mean_convergence
from .strata import strata

#: The plastic equilibrium tolerance: the out-of-balance force relative to the increment's
#: load (``solver.tolerance`` if coarser). The constant-stiffness iteration converges linearly;
#: with non-associated flow (ψ < φ) it stalls near 1e-4, where points cross the yield surface
#: from one iterate to the next. 1e-3 is ten times tighter than the 1 % commercial codes
#: default to; Salençon's wall convergence is met to 0.4 % with it (tests).
MIN_TOLERANCE = 1e-3
#: Iterations allowed per load increment before the case fails.
MAX_STEP_ITERATIONS = 500
#: Anderson mixing depth.
DEPTH = 8


class _Points:
    """The ground's stress history at one set of points (quadrature or output points)."""

    def __init__(self, model, spec, basis):
        self.basis = basis
        layers = strata(spec)
        self.layers = layers
        band = model.band
        y = np.asarray(basis.global_coordinates())[1]  # (E, Q)
        self.shape = y.shape
        young, poisson = moduli(model.layers, band, y)
        young = np.broadcast_to(young, y.shape)
        poisson = np.broadcast_to(poisson, y.shape)
        self.young, self.poisson = young, poisson
        lam = young * poisson / ((1 + poisson) * (1 - 2 * poisson))
        mu = young / (2 * (1 + poisson))
        per = lambda name: np.broadcast_to(  # noqa: E731
            np.array([getattr(s, name) for s in layers])[band][:, None], y.shape).ravel()
        self.yielding = np.broadcast_to(np.array([s.model == "mohr-coulomb" for s in layers])[band][:, None],
                                        y.shape).ravel()
        sel = self.yielding
        self.lam, self.mu = lam.ravel()[sel], mu.ravel()[sel]
        self.strength = {k: per(k)[sel] for k in ("cohesion", "friction_angle", "dilatancy", "tensile_strength")}
        self.sigma0 = (in_situ_stress(spec, layers, band, y)["effective"]  # (4, E, Q)
                       if spec.excavation.method == "deconfinement" else np.zeros((4,) + y.shape))
        self.sigma = self.sigma0.copy()  # at the last converged increment
        self.grad = np.zeros((2, 2) + y.shape)
        self.eqps = np.zeros(y.shape)
        self.at_yield = np.zeros(y.shape, bool)
        #: a point within this (relative) distance of the yield surface counts as at yield: the
        #: equilibrium iteration's tolerance leaves yielding points a hair inside it
        self.flag_tolerance = max(spec.solver.tolerance, MIN_TOLERANCE)

    def gradient(self, body, u_nodes: np.ndarray) -> np.ndarray:
        return self.basis.interpolate(body.full(u_nodes)).grad

    def trial(self, grad: np.ndarray):
        """Stress, plastic strain increment and yield flags of a displacement gradient since
        excavation, from the last converged increment."""
        d = _stress_components(grad - self.grad, self.young, self.poisson)
        trial = self.sigma + np.stack(d)
        stress = trial.reshape(4, -1).copy()
        dep = np.zeros((3, stress.shape[1]))
        flags = np.zeros(stress.shape[1], bool)
        sel = self.yielding
        if sel.any():
            s = self.strength
            ret, dp, fl = return_map(stress[:, sel], self.lam, self.mu, s["cohesion"], s["friction_angle"],
                                     s["dilatancy"], s["tensile_strength"], flag_tolerance=self.flag_tolerance)
            # at yield: on the surface, or flowing in this increment (a point the iteration's
            # tolerance leaves a hair inside the surface is still yielding)
            stress[:, sel], dep[:, sel], flags[sel] = ret, dp, fl | (np.abs(dp).max(axis=0) > 0)
        return stress.reshape(trial.shape), dep, flags.reshape(self.shape)

    def commit(self, grad, stress, dep, flags) -> None:
        self.grad, self.sigma = grad, stress
        self.eqps = self.eqps + equivalent(dep).reshape(self.shape)
        self.at_yield = flags


def _plastic_load(points: _Points, grad: np.ndarray, stress: np.ndarray) -> np.ndarray:
    """Full-DOF ``∫Bᵀ(σ0′ + D ε(u) - σ)`` at the quadrature points of ``points``: only the
    elements where the ground has yielded contribute (elsewhere the bracket is zero)."""
    basis = points.basis
    tau = points.sigma0 + np.stack(_stress_components(grad, points.young, points.poisson)) - stress
    scale = max(float(np.max(np.abs(stress))), 1.0)
    elements = np.flatnonzero(np.max(np.abs(tau), axis=(0, 2)) > 1e-12 * scale)
    if elements.size == 0:
        return np.zeros(basis.N)
    tau = tau[:, elements]
    dx = basis.dx[elements]
    out = np.empty((basis.Nbfun, elements.size))
    for i in range(basis.Nbfun):
        g = basis.basis[i][0].grad[:, :, elements]
        out[i] = np.sum((tau[0] * g[0, 0] + tau[1] * g[1, 1] + tau[2] * (g[0, 1] + g[1, 0])) * dx, axis=1)
    return np.bincount(basis.element_dofs[:, elements].ravel(), out.ravel(), minlength=basis.N)


class _Anderson:
    """Anderson acceleration (type II, depth ``m``) of a fixed-point iteration ``x ← G(x)``:
    the next iterate mixes the last ``m`` iterates so that their residuals ``G(x) - x``
    combine to the least one. The constant-stiffness iteration converges linearly, slowly
    when much of the ground yields; mixing turns it into a secant (multisecant) method at the
    cost of a small least-squares problem per iteration."""

    def __init__(self, m: int = 8):
        self.m, self.xs, self.rs = m, [], []

    def step(self, x: np.ndarray, gx: np.ndarray) -> np.ndarray:
        r = gx - x
        self.xs.append(gx)
        self.rs.append(r)
        if len(self.rs) > self.m + 1:
            self.xs.pop(0)
            self.rs.pop(0)
        if len(self.rs) == 1 or self.m == 0:
            return gx
        dR = np.column_stack([self.rs[i + 1] - self.rs[i] for i in range(len(self.rs) - 1)])
        dG = np.column_stack([self.xs[i + 1] - self.xs[i] for i in range(len(self.xs) - 1)])
        gamma = np.linalg.lstsq(dR, r, rcond=None)[0]
        return gx - dG @ gamma


def _fixed_point(G, x0: np.ndarray, K, atol: float, where: str):
    """Solve ``x = G(x)`` (``G`` returns the new iterate and the plastic load it used) by
    constant-stiffness iterations with Anderson mixing, until the out-of-balance force
    ``‖K (G(x) - x)‖`` is at most ``atol``."""
    acc = _Anderson(DEPTH)
    x, force = x0, float("inf")
    for count in range(1, MAX_STEP_ITERATIONS + 1):
        check_time("plastic iteration", count)
        gx, p = G(x)
        force = float(np.linalg.norm(K @ (gx - x)))
        if force <= atol:
            return gx, p, count
        x = acc.step(x, gx)
    raise NotConvergedError(
        f"solver.load_steps: the yielding ground did not reach equilibrium in {where} (out-of-balance force "
        f"{force:.3g} N/m > {atol:.3g} after {MAX_STEP_ITERATIONS} iterations): far above the tolerance the "
        "ground is collapsing (raise its strength or the support: a lower excavation.deconfinement); just above "
        "it the iteration has stalled where points cross the yield surface (more solver.load_steps, or a "
        f"coarser solver.tolerance: the plastic iteration's is max(solver.tolerance, {MIN_TOLERANCE:g}))")


def solve_staged(model, spec, rows, t0: float):
    """Solve a case whose ground can yield (see the module's docstring): a
    :class:`~solver.model.Solution` with ``plastic`` results filled."""
    from .model import Forward, StageLoads

    ground, lining = model.ground, model.lining
    body = ground.body
    gauss = _Points(model, spec, body.basis)
    out = _Points(model, spec, point_basis(body))
    loads = model.stage_loads(spec)
    steps = spec.solver.load_steps
    tol = max(spec.solver.tolerance, MIN_TOLERANCE)
    ld = spec.excavation.deconfinement if loads.release is not None else 0.0
    iterations, curve = 0, []
    iface = model.mesh.interface

    def stress_of(u_free):
        nodes = body.expand(u_free)
        grad = gauss.gradient(body, nodes)
        stress, dep, flags = gauss.trial(grad)
        return nodes, grad, stress, dep, flags

    def commit(nodes, grad, stress, dep, flags):
        gauss.commit(grad, stress, dep, flags)
        og = out.gradient(body, nodes)
        out.commit(og, *out.trial(og))

    # stage 1: λd r on the unsupported ground
    u1 = np.zeros(body.n)
    p1 = np.zeros(body.n)
    if loads.release is not None and ld > 0:
        y_r = ground.forward(loads.release, rows)
        for k in range(1, steps + 1):
            frac = ld * k / steps
            ref = frac * float(np.linalg.norm(loads.release))
            base = frac * y_r

            def G(x):
                nodes, grad, stress, dep, flags = stress_of(x)
                p = body.restrict(_plastic_load(gauss, grad, stress))
                return ground.backward(base + ground.forward(p, rows), rows), p

            u1, p, its = _fixed_point(G, u1, body.K, tol * ref, f"stage 1, increment {k} of {steps}")
            iterations += its
            nodes, grad, stress, dep, flags = stress_of(u1)
            p1 = p
            commit(nodes, grad, stress, dep, flags)
            curve.append((frac, mean_convergence(body.expand(u1), iface)))
    # stage 2: the rest, with the lining and contact
    full = StageLoads(loads.ground, loads.lining, None, loads.seepage)
    y_g = ground.forward(full.ground, rows)
    y_l = lining.forward(full.lining, rows)
    F2_full = float(model.rigid @ full.lining)
    u2 = np.zeros(body.n)
    last = {}
    for k in range(1, steps + 1):
        a = k / steps
        ref = a * float(np.linalg.norm(full.ground)) + float(np.linalg.norm(p1)) + abs(a * F2_full)

        def G(x):
            nodes, grad, stress, dep, flags = stress_of(u1 + x)
            p = body.restrict(_plastic_load(gauss, grad, stress))
            extra = p - p1
            stage = Forward(ground=a * y_g + ground.forward(extra, rows), lining=a * y_l)
            d = ground.jumps(stage.ground, rows) + lining.jumps(stage.lining, rows)
            sol = model._finish(spec, rows, StageLoads(a * full.ground + extra, a * full.lining, None), stage, d,
                                a * F2_full, t0, u1=u1)
            last["sol"] = sol
            return body.restrict(body.full(sol.u_ground)) - u1, p

        u2, p, its = _fixed_point(G, u2, body.K, tol * ref, f"stage 2, increment {k} of {steps}")
        iterations += its
        commit(*stress_of(u1 + u2))
    sol = last["sol"]  # the contact stage of the converged iterate
    E = out.shape[0]
    sol.plastic = {
        "stress": out.sigma.reshape(4, -1),
        "at_yield": out.at_yield.reshape(-1),
        "eqps": out.eqps.reshape(-1),
        "iterations": iterations,
        "ground_reaction": curve,
        "elements": E,
    }
    return sol

"""The exact limit state of issue 41, shared by the reliability tests and ``bench.study --reliability``.

Weightless ground, a light lining (1 kg/m³: the lining must weigh something, SPEC §1),
frictionless contact: every load is the surface load q times a fixed field, so N and M are
proportional to q. A station's utilization is positively homogeneous in (N, M) (the ray to the
envelope), and the design rule takes the worse of (γF N, γF M) and (1.0 N, γF M) (SPEC §9.3), so

    η(q, γF) = q/q0 · max(γF · max_s u(N_s, M_s), max_s u(N_s, γF M_s)),

u the ray utilization at γF = 1 — one solve at q0 and the stored envelope; linear in q, not in γF
(where bending governs, the unfactored thrust does). With q and γF lognormal its probability is
the integral P = ∫ f(γF) P(q > q*(γF)) dγF, q*(γF) = q0 / η(q0, γF), computed here with scipy; the
surface load of a study at a given β is found by solving P(mean) = Φ(-β) for the mean.
"""
from __future__ import annotations

import math

import numpy as np
from scipy import optimize, stats

from solver import CaseSpec, run_case
from solver.lining.design import design_utilization, interaction_envelope

COARSE = {"mesh": {"interface_size": 0.25, "far_size": 8.0}}
EXACT = {**COARSE, "ground": {"density": 0.0}, "lining": {"density": 1.0}, "geometry": {"thickness": 0.2},
         "design": {"concrete_strength": 1.6e7, "load_factor": 1.0}}
Q0 = 1.0e5
COV_Q = 0.3
GAMMA = {"distribution": "lognormal", "mean": 1.35, "std": 0.1}
GRID = (0.5, 3.0)  # the γF range of the exact pieces (|z| < 13 of GAMMA; outside it: direct)


def _envelope(spec: CaseSpec) -> tuple[np.ndarray, np.ndarray]:
    d = spec.design
    return interaction_envelope(spec.geometry.thickness, concrete_strength=d.concrete_strength,
                                steel_strength=d.steel_strength, reinforcement_area=d.reinforcement_area,
                                axis_distance=d.axis_distance)


def lognormal(mean: float, std: float) -> tuple[float, float]:
    s2 = math.log1p((std / mean) ** 2)
    return math.log(mean) - 0.5 * s2, math.sqrt(s2)


class ExactLimitState:
    """η(q, γF) from one solve, by the code path of the FE result (design_utilization)."""

    def __init__(self, mesh: dict | None = None):
        #: the case every study of it varies: EXACT, on ``mesh`` if given (the tests' cheaper one)
        self.base = EXACT if mesh is None else {**EXACT, "mesh": mesh}
        spec = CaseSpec.model_validate({**self.base, "loads": {"surface_load": Q0}})
        ds = run_case(spec)
        self.N, self.M = ds["thrust"].values, ds["moment"].values
        self.spec = spec
        self.eta1 = float(ds["max_utilization"]) / Q0  # per Pa at γF = 1
        self._unit = spec.design.model_copy(update={"load_factor": 1.0})
        self._loads: dict[float, dict] = {}  # surface_load's answers
        self._full = self._ray(self.N, self.M).max()  # max_s u(N_s, M_s)
        # the stations that can govern (1.0 N, γF M) for γF in GRID: those within 10 % of the
        # largest at some grid level (u is Lipschitz in γF and the grid is fine, so an argmax
        # between grid levels is among them); γF outside GRID uses every station
        # the stations that can govern (1.0 N, γF M) on GRID: within 5 % of the largest at some
        # level of a fine grid (u moves by less between its levels); their pieces are exact
        levels = np.linspace(*GRID, 201)
        u = self._ray(np.broadcast_to(self.N, (levels.size, self.N.size)), levels[:, None] * self.M)
        near = (u >= 0.95 * u.max(axis=1, keepdims=True)).any(axis=0)
        self._pieces = [self._piecewise(n, m) for n, m in zip(self.N[near], self.M[near])]

    def _ray(self, N, M) -> np.ndarray:
        """u(N, M): the ray utilization at γF = 1 (both combinations coincide there)."""
        return design_utilization(N, M, self.spec.geometry.thickness, self._unit)[0]

    def _piecewise(self, n: float, m: float) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """u(n, γ m) on GRID as exact pieces (breaks, slopes, intercepts): along γ the ray's
        exit η = (n e_m − γ m e_n) / (P_i × P_i+1) is linear in γ on an edge, and the edge hit
        changes only where the ray crosses a vertex (γ = n a_m / (m a_n)) or an edge's η
        crosses 0; each piece is fitted at its thirds and checked at its middle."""
        env_N, env_M = _envelope(self.spec)
        with np.errstate(divide="ignore", invalid="ignore"):
            cuts = np.concatenate([n * env_M / (m * env_N),
                                   n * np.diff(env_M) / (m * np.diff(env_N))])
        cuts = cuts[np.isfinite(cuts) & (cuts > GRID[0]) & (cuts < GRID[-1])]
        breaks = np.unique(np.concatenate([[GRID[0], GRID[-1]], cuts]))
        lo, width = breaks[:-1], np.diff(breaks)
        at = lo[:, None] + width[:, None] * np.array([1 / 3, 1 / 2, 2 / 3])
        u = self._ray(np.full(at.shape, n), m * at)
        slope = (u[:, 2] - u[:, 0]) / (at[:, 2] - at[:, 0])
        intercept = u[:, 0] - slope * at[:, 0]
        middle = intercept + slope * at[:, 1]
        assert np.allclose(middle, u[:, 1], rtol=1e-12, atol=0), "u(n, γ m) not linear between the breaks"
        return breaks, slope, intercept

    def direct_utilization(self, q: float, gamma: float) -> float:
        """max_utilization at (q, γF) through design_utilization, as the FE result computes it."""
        design = self.spec.design.model_copy(update={"load_factor": float(gamma)})
        eta, _, _ = design_utilization(q / Q0 * self.N, q / Q0 * self.M, self.spec.geometry.thickness, design)
        return float(np.nanmax(eta))

    def utilization(self, q, gamma) -> np.ndarray:
        """max_utilization at surface loads ``q`` and load factors ``gamma`` (broadcast), by the
        homogeneity of the module's docstring; :meth:`direct_utilization` is the check."""
        q, gamma = np.broadcast_arrays(np.asarray(q, float), np.asarray(gamma, float))
        levels, inverse = np.unique(gamma, return_inverse=True)
        favourable = np.full(levels.size, -np.inf)
        inside = (levels >= GRID[0]) & (levels <= GRID[-1])
        for breaks, slope, intercept in self._pieces:
            k = np.clip(np.searchsorted(breaks, levels[inside], side="right") - 1, 0, slope.size - 1)
            favourable[inside] = np.maximum(favourable[inside], intercept[k] + slope[k] * levels[inside])
        for j in np.flatnonzero(~inside):  # rare: outside GRID, directly
            favourable[j] = self._ray(self.N, levels[j] * self.M).max()
        at_q0 = np.maximum(levels * self._full, favourable)[inverse].reshape(gamma.shape)
        return q / Q0 * at_q0

    def surface_load(self, beta: float) -> dict:
        """The lognormal surface load (c.o.v. 0.3) whose study with γF has the reliability index
        ``beta``: P(mean) = Φ(-β) solved for the mean, from the value the linear rule would give."""
        mg, sg = lognormal(GAMMA["mean"], GAMMA["std"])
        sq = math.sqrt(math.log1p(COV_Q ** 2))
        guess = -math.log(self.eta1) - mg - beta * math.hypot(sq, sg)
        target = math.log(stats.norm.sf(beta))

        def load(mq):
            mean = math.exp(mq + 0.5 * sq ** 2)
            return {"distribution": "lognormal", "mean": mean, "std": COV_Q * mean}

        def residual(mq):
            p = self.probability({"variables": {"loads.surface_load": load(mq)}})
            return math.log(p) - target

        if beta not in self._loads:
            span = 0.05  # the favourable combination moves η by a few per cent at most
            while residual(guess - span) * residual(guess + span) > 0:
                span *= 4
            self._loads[beta] = load(optimize.brentq(residual, guess - span, guess + span, xtol=1e-12, rtol=1e-12))
        return dict(self._loads[beta])

    def study(self, beta: float, method: str, budget: int, seed: int = 1) -> dict:
        return {"name": f"exact-{method}-{beta}", "base": self.base, "method": method, "budget": budget, "seed": seed,
                "variables": {"loads.surface_load": self.surface_load(beta), "design.load_factor": GAMMA}}

    def probability(self, study: dict) -> float:
        """The exact P(η > 1) = ∫ φ(z) P(q > q*(γF(z))) dz by quadrature over γF."""
        mq, sq = lognormal(study["variables"]["loads.surface_load"]["mean"],
                           study["variables"]["loads.surface_load"]["std"])
        mg, sg = lognormal(GAMMA["mean"], GAMMA["std"])

        # composite 8-point Gauss–Legendre on z (γF's standard normal variable) in [-8, 8]:
        # 3 200 panels of 0.005, vectorized; η's kinks in γF cost 1e-9 of P (checked against quad)
        x, w = np.polynomial.legendre.leggauss(8)
        edges = np.linspace(-8.0, 8.0, 3201)
        half = 0.5 * np.diff(edges)
        z = ((edges[:-1] + half)[:, None] + half[:, None] * x).ravel()
        weights = (half[:, None] * w).ravel()
        q_star = Q0 / self.utilization(Q0, np.exp(mg + sg * z))
        return float(np.sum(weights * stats.norm.pdf(z) * stats.norm.sf((np.log(q_star) - mq) / sq)))

    def limit_state(self, study: dict):
        """g(u) = 1 − η(x(u)) as a :class:`FunctionLimitState` with the study's budget."""
        from workflows.reliability_methods import FunctionLimitState, ReliabilityStudy
        from workflows.reliability_methods.space import StandardSpace

        s = ReliabilityStudy.model_validate(study)
        space = StandardSpace(list(s.variables.values()))

        def g(U):
            X = space.to_physical(U)
            return 1.0 - self.utilization(X[:, 0], X[:, 1])

        return FunctionLimitState(g, 2, s.budget)

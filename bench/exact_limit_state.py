"""The exact limit state of issue 41, shared by the reliability tests and ``bench.study --reliability``.

Weightless ground, a light lining (1 kg/m³: the lining must weigh something, SPEC §1),
frictionless contact: every load is the surface load q times a fixed field, so N and M are
proportional to q, and the utilization, linear in (γF N, γF M) along its ray, is
η(q, γF) = max over stations of design_utilization(q/q0 N0, q/q0 M0; γF) — one solve at q0
and the stored envelope. With q and γF lognormal its probability is the integral
P = ∫ f(γF) P(q > q*(γF)) dγF, q*(γF) = q0 / η(q0, γF), computed here with scipy.
"""
from __future__ import annotations

import math

import numpy as np
from scipy import integrate, stats

from solver import CaseSpec, run_case
from solver.lining.design import design_utilization

COARSE = {"mesh": {"interface_size": 0.25, "far_size": 8.0}}
EXACT = {**COARSE, "ground": {"density": 0.0}, "lining": {"density": 1.0}, "geometry": {"thickness": 0.2},
         "design": {"concrete_strength": 1.6e7, "load_factor": 1.0}}
Q0 = 1.0e5
COV_Q = 0.3
GAMMA = {"distribution": "lognormal", "mean": 1.35, "std": 0.1}


def lognormal(mean: float, std: float) -> tuple[float, float]:
    s2 = math.log1p((std / mean) ** 2)
    return math.log(mean) - 0.5 * s2, math.sqrt(s2)


class ExactLimitState:
    """η(q, γF) from one solve, by the code path of the FE result (design_utilization)."""

    def __init__(self):
        spec = CaseSpec.model_validate({**EXACT, "loads": {"surface_load": Q0}})
        ds = run_case(spec)
        self.N, self.M = ds["thrust"].values, ds["moment"].values
        self.spec = spec
        self.eta1 = float(ds["max_utilization"]) / Q0  # per Pa at γF = 1
        self.eta_unit = self.direct_utilization(Q0, 1.0)

    def direct_utilization(self, q: float, gamma: float) -> float:
        """max_utilization at (q, γF) through design_utilization, as the FE result computes it."""
        design = self.spec.design.model_copy(update={"load_factor": float(gamma)})
        eta, _, _ = design_utilization(q / Q0 * self.N, q / Q0 * self.M, self.spec.geometry.thickness, design)
        return float(np.nanmax(eta))

    def utilization(self, q, gamma) -> np.ndarray:
        """max_utilization at surface loads ``q`` and load factors ``gamma`` (broadcast): η of a
        station is positively homogeneous in (γF N, γF M) (the ray to the envelope), so it is
        γF q/q0 times η at (q0, 1); :meth:`direct_utilization` is the check."""
        q, gamma = np.broadcast_arrays(np.asarray(q, float), np.asarray(gamma, float))
        return gamma * q / Q0 * self.eta_unit

    def surface_load(self, beta: float) -> dict:
        """The lognormal surface load (c.o.v. 0.3) whose study with γF has the reliability index
        ``beta`` (from the proportionality; :meth:`probability` checks it by integration)."""
        mg, sg = lognormal(GAMMA["mean"], GAMMA["std"])
        sq = math.sqrt(math.log1p(COV_Q ** 2))
        mq = -math.log(self.eta1) - mg - beta * math.hypot(sq, sg)
        mean = math.exp(mq + 0.5 * sq ** 2)
        return {"distribution": "lognormal", "mean": mean, "std": COV_Q * mean}

    def study(self, beta: float, method: str, budget: int, seed: int = 1) -> dict:
        return {"name": f"exact-{method}-{beta}", "base": EXACT, "method": method, "budget": budget, "seed": seed,
                "variables": {"loads.surface_load": self.surface_load(beta), "design.load_factor": GAMMA}}

    def probability(self, study: dict) -> float:
        """The exact P(η > 1) by quadrature over γF."""
        mq, sq = lognormal(study["variables"]["loads.surface_load"]["mean"],
                           study["variables"]["loads.surface_load"]["std"])
        mg, sg = lognormal(GAMMA["mean"], GAMMA["std"])

        def integrand(z):  # z: γF's standard normal variable
            gamma = math.exp(mg + sg * z)
            q_star = Q0 / float(self.utilization(Q0, gamma))
            return stats.norm.pdf(z) * stats.norm.sf((math.log(q_star) - mq) / sq)

        return integrate.quad(integrand, -8, 8, epsabs=0, epsrel=1e-10, limit=200)[0]

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

"""The discrete KKT residual every contact answer is checked by (before it is a result)."""
from __future__ import annotations

import numpy as np


def kkt_residual(*, K_u_minus_f: list[tuple[np.ndarray, np.ndarray]], balance: float, balance_scale: float,
                 lam: np.ndarray, normal_jump: np.ndarray, g0: float, p_ref: float, u_ref: float,
                 model: str = "frictionless", shear: np.ndarray | None = None,
                 tangential_jump: np.ndarray | None = None, mu: float = 0.0) -> float:
    """Largest relative violation of the discrete KKT conditions (dimensionless).

    ``K_u_minus_f`` holds per body the residual ``K u + Bᵀ W t - f`` and the size of the
    forces it balances; ``balance`` is ``F2 + I(λ ν2 + s τ2)`` (N/m), relative to
    ``balance_scale`` = ``|F2| + I|λ ν2 + s τ2|`` (not ``|F2|`` alone: a lining as light as the
    water it displaces has F2 ≈ 0 while the interface carries megapascals); the gap is
    ``g0 - normal_jump``. Pressures are scaled by ``p_ref`` (Pa), jumps and gaps by
    ``u_ref`` (m). By model:

    - frictionless / coulomb: λ ≥ 0, gap ≥ 0, λ·gap = 0;
    - coulomb adds the friction law through its natural map,
      ``|s - proj_[-μλ, μλ](s + c [u]τ)| / p_ref`` with ``c = p_ref / u_ref``: zero iff
      |s| ≤ μλ, [u]τ = 0 where |s| < μλ, and [u]τ parallel to s where |s| = μλ
      (the lining slips against s relative to the ground);
    - bonded: the jumps [u]ν and [u]τ themselves, which the tie makes zero (the clearance
      g0, if any, is kept as it was when the lining was placed).
    """
    parts = [np.max(np.abs(r)) / max(np.max(np.abs(f)), 1e-300) for r, f in K_u_minus_f]
    parts.append(abs(balance) / max(balance_scale, 1e-300))
    if model == "bonded":
        parts.append(float(np.max(np.abs(normal_jump))) / u_ref)
        parts.append(float(np.max(np.abs(tangential_jump))) / u_ref)
        return float(max(parts))
    gap = g0 - normal_jump
    parts.append(max(0.0, -float(lam.min())) / p_ref)
    parts.append(max(0.0, -float(gap.min())) / u_ref)
    parts.append(float(np.max(np.abs(lam * gap))) / (p_ref * u_ref))
    if model == "coulomb":
        c = p_ref / u_ref
        bound = mu * np.maximum(lam, 0.0)
        nat = shear - np.clip(shear + c * tangential_jump, -bound, bound)
        parts.append(float(np.max(np.abs(nat))) / p_ref)
    return float(max(parts))

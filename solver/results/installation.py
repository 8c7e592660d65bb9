"""A face-distance case's results (SPEC §9.5): the λd used, the profile's u*, and how they were found."""
from __future__ import annotations

import numpy as np

from ..stages.state import Solution


def installation_scalars(sol: Solution) -> dict:
    """``deconfinement`` (λd used) and ``ldp_ratio`` (u*; 0 unless the face distance gave λd, as
    the other scalars of what a case does not have)."""
    found = sol.installation
    return {"deconfinement": float(sol.spec.excavation.deconfinement),
            "ldp_ratio": found.ldp_ratio if found is not None else 0.0}


def installation_attrs(sol: Solution) -> dict:
    """How a face-distance case's λd was found (SPEC §9.5), as one attribute."""
    found, exc = sol.installation, sol.spec.excavation
    if found is None:
        return {}
    return {"installation": {
        "face_distance_m": exc.face_distance, "ldp": exc.ldp, "excavation_radius_m": found.radius,
        "plastic_radius_ratio": found.plastic_ratio, "ldp_ratio": found.ldp_ratio,
        "full_release_convergence_m": (None if np.isnan(found.full_release_convergence)
                                       else found.full_release_convergence),
        "full_release_curve": [{"released": f, "wall_convergence_m": c} for f, c in found.full_release_curve],
        "deconfinement": found.deconfinement}}

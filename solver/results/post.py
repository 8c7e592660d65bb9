"""Measures of a solved case: the contact's extent, the surface trough, the wall's mean convergence."""
from __future__ import annotations

import numpy as np


def contact_extent(theta_deg: np.ndarray, in_contact: np.ndarray) -> float:
    """Degrees of interface in contact (each node owns half of its neighbouring intervals)."""
    dth = np.diff(theta_deg)
    own = 0.5 * (np.r_[0.0, dth] + np.r_[dth, 0.0])
    return float(np.sum(own * in_contact))


def surface_trough(ground_p: np.ndarray, u_ground: np.ndarray, *, scale: float) -> tuple[np.ndarray, np.ndarray]:
    """x (ascending, m) and settlement (m, downward positive) of the ground surface y = 0."""
    top = np.flatnonzero(np.abs(ground_p[1]) <= 1e-9 * scale)
    order = top[np.argsort(ground_p[0, top])]
    return ground_p[0, order], -u_ground[1, order]


def mean_convergence(u: np.ndarray, iface) -> float:
    """Inward radial displacement (m) of the ground wall, averaged over the interface."""
    inward = np.sum(u[:, iface.ground_node] * iface.normal, axis=0)
    return float(np.sum(iface.weight * inward) / np.sum(iface.weight))

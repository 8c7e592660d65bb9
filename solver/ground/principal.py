"""Principal stresses of plane strain and back: what every isotropic yield law and its tangent share."""
from __future__ import annotations

import numpy as np


def principal(stress: np.ndarray):
    """Principal values of plane-strain stresses (4, ...) = (xx, yy, xy, zz): the in-plane pair
    (major, minor), the angle of the major direction and σzz."""
    sxx, syy, sxy, szz = stress
    c = 0.5 * (sxx + syy)
    r = np.hypot(0.5 * (sxx - syy), sxy)
    angle = 0.5 * np.arctan2(2.0 * sxy, sxx - syy)
    return c + r, c - r, angle, szz


def from_principal(major, minor, angle, szz) -> np.ndarray:
    """Plane-strain stress components (4, ...) from in-plane principal values along ``angle``."""
    c, s = np.cos(angle), np.sin(angle)
    return np.stack([major * c * c + minor * s * s, major * s * s + minor * c * c, (major - minor) * s * c, szz])

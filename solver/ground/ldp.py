"""Longitudinal displacement profiles (SPEC §9.5): the wall convergence at a distance from the
face as a share of the convergence far behind it, u*(X*) = u(x) / u_max, X* = x / R (x > 0
behind the face, where the support is installed; x < 0 ahead of it).

Plain functions of the dimensionless distance; the share of the excavation load the ground has
released where the lining is installed is then read off the case's own ground reaction curve
(:mod:`solver.stages.face`).

- Vlachopoulos & Diederichs (2009), with R* = plastic radius / R at full release:
  u₀* = e^(−0.15 R*) / 3 at the face, u* = u₀* e^(X*) ahead of it,
  u* = 1 − (1 − u₀*) e^(−3X* / (2R*)) behind it.
- Panet (1995), behind the face only: u* = 0.25 + 0.75 [1 − (0.75 / (0.75 + X*))²].
- Hoek (2008, the fit to Chern et al.'s measurements): u* = (1 + e^(−X*/1.1))^(−1.7).
- Unlu & Gercek (2003), with the ground's Poisson ratio ν: u₀* = 0.22ν + 0.19 at the face,
  u* = u₀* e^((0.73ν + 0.81) X*) ahead of it,
  u* = u₀* + (0.81 − 0.22ν) [1 − (B / (B + X*))²], B = 0.39ν + 0.65, behind it.
"""
from __future__ import annotations

import math

#: The profiles ``excavation.ldp`` names.
PROFILES = ("vlachopoulos-diederichs", "panet", "hoek", "unlu-gercek")


def vlachopoulos_diederichs(x: float, plastic_ratio: float = 1.0) -> float:
    """u* at X* = ``x`` for the plastic radius over the tunnel radius ``plastic_ratio`` (R* ≥ 1;
    1 for ground that stays elastic)."""
    if plastic_ratio < 1.0:
        raise ValueError(f"plastic radius ratio R* = {plastic_ratio:g} is below 1")
    face = math.exp(-0.15 * plastic_ratio) / 3.0
    if x <= 0.0:
        return face * math.exp(x)
    return 1.0 - (1.0 - face) * math.exp(-1.5 * x / plastic_ratio)


def panet(x: float) -> float:
    """u* at X* = ``x`` ≥ 0 (Panet's profile is defined behind the face only)."""
    if x < 0.0:
        raise ValueError(f"Panet's profile is defined behind the face (X* >= 0), not at X* = {x:g}")
    return 0.25 + 0.75 * (1.0 - (0.75 / (0.75 + x)) ** 2)


def hoek(x: float) -> float:
    """u* at X* = ``x``."""
    return (1.0 + math.exp(-x / 1.1)) ** -1.7


def unlu_gercek(x: float, poisson: float) -> float:
    """u* at X* = ``x`` for the ground's Poisson ratio ``poisson``."""
    face = 0.22 * poisson + 0.19
    if x <= 0.0:
        return face * math.exp((0.73 * poisson + 0.81) * x)
    b = 0.39 * poisson + 0.65
    return face + (0.81 - 0.22 * poisson) * (1.0 - (b / (b + x)) ** 2)


def ldp_ratio(profile: str, x: float, *, plastic_ratio: float = 1.0, poisson: float = 0.3) -> float:
    """u*(X*) of the profile ``profile`` (one of :data:`PROFILES`); ``plastic_ratio`` serves
    Vlachopoulos & Diederichs, ``poisson`` Unlu & Gercek."""
    if profile == "vlachopoulos-diederichs":
        return vlachopoulos_diederichs(x, plastic_ratio)
    if profile == "panet":
        return panet(x)
    if profile == "hoek":
        return hoek(x)
    if profile == "unlu-gercek":
        return unlu_gercek(x, poisson)
    raise ValueError(f"unknown longitudinal displacement profile {profile!r}; one of {', '.join(PROFILES)}")

"""The ground's constitutive laws as the plastic driver sees them: callables of trial stresses.

A law is ``law(trial (4, n), tangent: bool, frozen=None) -> (stress (4, n), plastic strain (3, n),
at_yield (n,), returned (r,), C (r, 4, 4))``: the return from elastic trial stresses (plane
strain, tension positive, (xx, yy, xy, zz)), the plastic strain increment in principal axes, the
points at or beyond the surface, the points it returned and, if ``tangent``, their algorithmic
tangent (strain increments (dεxx, dεyy, dγxy, dεzz) to stress increments; the elastic matrix
elsewhere). ``frozen`` (n,) bool fixes which points flow (a smooth return: an active-set step of
the equilibrium iteration, see :func:`.mohr_coulomb.consistent_tangent`).
The FE loop (:mod:`solver.stages.points`) knows nothing else of the law.
"""
from __future__ import annotations

from typing import Callable

import numpy as np

from . import mohr_coulomb

Law = Callable[[np.ndarray, bool], tuple]

#: A point within this fraction of its stress scale inside its yield surface counts as at yield
#: (the reported ``plastic`` flags; the return and its tangent act on points outside only).
FLAG_TOLERANCE = 1e-3


def mohr_coulomb_law(material: mohr_coulomb.Material, flag_tolerance: float = FLAG_TOLERANCE) -> Law:
    """Mohr–Coulomb with tension cut-off (:mod:`.mohr_coulomb`) of per-point constants ``material``."""
    def law(trial: np.ndarray, tangent: bool, frozen: np.ndarray | None = None):
        if tangent or frozen is not None:
            return mohr_coulomb.consistent_tangent(trial, material, flag_tolerance, frozen)
        stress, dep, at_yield = mohr_coulomb.return_stress(trial, material, flag_tolerance)
        return stress, dep, at_yield, None, None

    return law


def ground_laws(layers, band: np.ndarray, lam: np.ndarray, mu: np.ndarray) -> list[tuple[np.ndarray, Law]]:
    """The yielding layers' laws at the points (E, Q) of the ground: ``(points, law)`` pairs, the
    points as flat indices; ``band`` (E,) the layer of each element, ``lam``, ``mu`` (E, Q) Pa."""
    E, Q = lam.shape
    out = []
    for index, layer in enumerate(layers):
        if layer.model == "elastic":
            continue
        points = (np.flatnonzero(band == index)[:, None] * Q + np.arange(Q)).ravel()
        if points.size == 0:
            continue
        if layer.model == "mohr-coulomb":
            material = mohr_coulomb.Material.of(points.size, lam.ravel()[points], mu.ravel()[points],
                                                layer.cohesion, layer.friction_angle, layer.dilatancy,
                                                layer.tensile_strength)
            out.append((points, mohr_coulomb_law(material)))
        else:
            raise ValueError(f"ground model {layer.model!r} has no law")
    return out

"""Where the lining is installed behind the face (SPEC §9.5): the deconfinement found, not given.

The wall convergence at installation is u*(X*)·u_max of the case's longitudinal displacement
profile (:mod:`solver.ground.ldp`), X* = face distance / R, R the excavation radius; λd is where
the case's own stage-1 ground reaction curve reaches that convergence. For ground that stays
elastic the curve is a straight line through the origin, so λd = u* without a solve. For
ground that can yield the full release is solved once on the built model (stage 1 alone,
:func:`solver.stages.plastic.release_unsupported`): its last point is u_max, its plastic zone
gives R* (the radius of the ring of yielded ground's area around the excavation, over R), and the curve,
interpolated monotonically (PCHIP) through its increments, is inverted at u*·u_max.
"""
from __future__ import annotations

import logging
import math

import numpy as np
from scipy.interpolate import PchipInterpolator

from ..errors import NotConvergedError
from ..ground.ldp import ldp_ratio
from ..ground.strata import strata
from ..spec import CaseSpec
from .plastic import release_unsupported, stage_one_key
from .state import Installation

log = logging.getLogger(__name__)


def excavation_radius(spec: CaseSpec) -> float:
    """R (m): the excavation's radius, the outer radius of the lining plus the clearance
    (for other shapes than the circle, the radius of the circle of equal excavated area)."""
    return spec.geometry.hole_radius


def axis_poisson(spec: CaseSpec) -> float:
    """The ground's Poisson ratio at the tunnel axis (the layer the axis lies in)."""
    depth = spec.geometry.depth
    layers = strata(spec)
    return next((s.poisson for s in layers if s.top <= depth < s.bottom), layers[-1].poisson)


def with_deconfinement(spec: CaseSpec, deconfinement: float) -> CaseSpec:
    """``spec`` with λd set (its face distance kept, so its canonical JSON and id are unchanged)."""
    return spec.model_copy(update={"excavation": spec.excavation.model_copy(update={"deconfinement": deconfinement})})


def install(model, spec: CaseSpec, rows) -> Installation:
    """λd of a face-distance case on its built ``model`` (factorized for ``rows``)."""
    exc = spec.excavation
    radius = excavation_radius(spec)
    x = exc.face_distance / radius
    if not spec.plastic:
        ratio = ldp_ratio(exc.ldp, x, plastic_ratio=1.0, poisson=axis_poisson(spec))
        return Installation(deconfinement=ratio, ldp_ratio=ratio, radius=radius, plastic_ratio=1.0)
    curve, plastic_ratio = full_release(model, spec, rows, radius)
    ratio = ldp_ratio(exc.ldp, x, plastic_ratio=plastic_ratio, poisson=axis_poisson(spec))
    u_max = curve[-1][1]
    found = invert_curve(curve, ratio * u_max)
    log.info("face distance %.4g m: u* = %.4g, R* = %.4g, u_max = %.4g m, deconfinement %.4g",
             exc.face_distance, ratio, plastic_ratio, u_max, found)
    return Installation(deconfinement=found, ldp_ratio=ratio, radius=radius, plastic_ratio=plastic_ratio,
                        full_release_convergence=u_max, full_release_curve=tuple(curve))


def plastic_radius(points, radius: float) -> float:
    """R* of the full release: the radius of the circle whose ring around the excavation (of the
    equal-area radius ``radius``) has the area of the yielded ground, over ``radius`` (1 when
    nothing yielded). An area, not the farthest yielded point: ground that yields far from the
    tunnel (in tension near the surface, at the model's corners) would otherwise set R*."""
    yielded = (points.eqps > 0) | points.at_yield
    area = 2.0 * float(np.sum(np.asarray(points.weights)[yielded]))  # both halves
    return math.sqrt(area / math.pi + radius**2) / radius


def invert_curve(curve, convergence: float) -> float:
    """The released share at which the ground reaction curve [(released, convergence)] (from
    the origin, increasing) reaches ``convergence``: the monotone cubic (PCHIP) through its
    points, inverted."""
    f = np.r_[0.0, [p[0] for p in curve]]
    c = np.r_[0.0, [p[1] for p in curve]]
    keep = np.r_[True, np.diff(c) > 0]  # a strictly increasing abscissa for the inverse
    f, c = f[keep], c[keep]
    if convergence >= c[-1]:
        return float(f[-1])
    if c.size == 2:
        return float(f[-1] * convergence / c[-1])
    return float(np.clip(PchipInterpolator(c, f)(convergence), 0.0, f[-1]))


def full_release(model, spec: CaseSpec, rows, radius: float) -> tuple[list, float]:
    """The full-release ground reaction curve and R* of ``spec``'s ground on ``model``, solved once
    per physics (the case less its stages: its face distance, profile and λd do not enter) and
    kept on the model (:class:`~solver.build.Kept`), so that a sweep over the
    face distance solves it once."""
    released = with_deconfinement(spec, 1.0)
    released = released.model_copy(update={"excavation": released.excavation.model_copy(
        update={"face_distance": None, "ldp": "vlachopoulos-diederichs"})})

    def compute():
        curve, points = _full_release(model, released, rows)
        return curve, plastic_radius(points, radius)

    return model.kept.get("release", stage_one_key(released, rows), compute)


def _full_release(model, spec: CaseSpec, rows):
    try:
        return release_unsupported(model, spec, rows, 1.0)
    except NotConvergedError as exc:
        raise type(exc)(
            f"excavation.face_distance: the full release of the unsupported ground, which the longitudinal "
            f"displacement profile is scaled by (u_max, R*), did not reach equilibrium; give "
            f"excavation.deconfinement instead (or, where the ground is collapsing, a stronger ground; "
            f"where the iteration stalled, a coarser solver.plastic_tolerance): {exc}") from None

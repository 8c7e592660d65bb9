"""The tunnel's section as a curve (SPEC §9.4): the half intrados from the crown to the invert,
its points, normals, arc length and curvature, and its outward normal offsets (the extrados,
the excavation). Pure geometry: no gmsh, no spec; the mesh asks a :class:`Profile` for its
pieces and their points.

Coordinates are relative to the section's centre, the point on the axis midway between crown
and invert; the half profile runs clockwise on the right (x ≥ 0) from the crown (x = 0, top,
horizontal tangent) to the invert (x = 0, bottom). The parameter of a point is its tangent's
turning angle φ from the crown (0 at the crown, π at the invert): the outward normal there is
(sin φ, cos φ), for every convex profile here.

- A polycentric profile is tangent-continuous circular arcs, radii Rᵢ > 0 and angles αᵢ summing
  to 180°; it closes on the axis when Σ Rᵢ (sin φᵢ₊₁ − sin φᵢ) = 0 (φᵢ the turning angle where arc
  i starts), which fixes the last radius (:func:`close_polycentric`). A circle is one such arc of
  180° (or two of equal radius, or any split).
- An ellipse (axes W/2, H/2) is parametrized by the same turning angle; its normal offset is not
  an ellipse.
- The offset of a convex profile by d outward (the lining's thickness, the clearance) has the same
  normals and turning angles; arc radii grow by d with the same centres.
"""
from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np


class SectionError(ValueError):
    """A profile that cannot be built; ``field`` names the input at fault (relative to the section)."""

    def __init__(self, field: str, reason: str):
        super().__init__(f"{field}: {reason}")
        self.field, self.reason = field, reason


@dataclass(frozen=True)
class Arc:
    """A circular arc of the profile: centre (m, relative to the section's centre), radius (m),
    and the turning angles (rad) where it starts and ends."""

    center: tuple[float, float]
    radius: float
    start: float
    end: float

    def at(self, phi: np.ndarray) -> np.ndarray:
        """(2, n) points at turning angles ``phi`` (rad, within [start, end])."""
        return np.asarray(self.center, float)[:, None] + self.radius * np.stack([np.sin(phi), np.cos(phi)])

    @property
    def length(self) -> float:
        return self.radius * (self.end - self.start)


def close_polycentric(radii: list[float | None], angles_deg: list[float]) -> float:
    """The last arc's radius (m) that closes the half profile on the axis, from the other arcs'
    ``radii`` (the last entry ignored) and every arc's angle (deg, summing to 180). Raises
    :class:`SectionError` naming ``arcs.<i>.radius`` or ``arcs.<i>.angle`` where it cannot close."""
    n = len(angles_deg)
    if n == 0:
        raise SectionError("arcs", "at least one arc")
    total = sum(angles_deg)
    if abs(total - 180.0) > 1e-9 * 180.0:
        raise SectionError(f"arcs.{n - 1}.angle", f"the arcs' angles sum to {total:.9g} deg, not 180")
    phi = np.radians(np.r_[0.0, np.cumsum(angles_deg)])
    phi[-1] = math.pi
    ds = np.diff(np.sin(phi))
    if abs(ds[-1]) < 1e-9:
        raise SectionError(f"arcs.{n - 1}.angle",
                           "the last arc spans symmetrically about the springline, so its radius cannot close "
                           "the profile; split the arcs differently")
    reach = sum(r * d for r, d in zip(radii[:-1], ds[:-1]))
    last = -reach / ds[-1]
    if not last > 0:
        raise SectionError(f"arcs.{n - 1}.radius",
                           f"the profile cannot close on the axis: the last arc would need a radius of {last:.6g} m "
                           "(not positive); change the other arcs' radii or angles")
    return float(last)


@dataclass(frozen=True)
class Profile:
    """A convex half profile: tangent-continuous circular ``arcs`` (a polycentric section), or
    the ``ellipse`` semi-axes (a, b) = (W/2, H/2); offset by ``offset`` (m) along its outward
    normal. Coordinates relative to the section's centre (see the module's docstring)."""

    arcs: tuple[Arc, ...] = ()
    ellipse: tuple[float, float] | None = None
    offset: float = 0.0

    @property
    def height(self) -> float:
        """Crown to invert (m)."""
        return float(self.points(np.array([0.0]))[1, 0] - self.points(np.array([math.pi]))[1, 0])

    def offset_by(self, d: float) -> "Profile":
        """This profile moved ``d`` (m) along its outward normal (the same centre of section)."""
        return Profile(self.arcs, self.ellipse, self.offset + d)

    def points(self, phi: np.ndarray) -> np.ndarray:
        """(2, n) points at turning angles ``phi`` (rad, 0 at the crown, π at the invert)."""
        phi = np.asarray(phi, float)
        normal = self.normals(phi)
        if self.ellipse is not None:
            a, b = self.ellipse
            # the point of the ellipse whose normal is (sin φ, cos φ): (a² sin φ, b² cos φ) / h
            h = np.hypot(a * np.sin(phi), b * np.cos(phi))
            base = np.stack([a * a * np.sin(phi), b * b * np.cos(phi)]) / h
        else:
            base = np.empty((2, phi.size))
            for k, arc in enumerate(self.arcs):
                last = k == len(self.arcs) - 1
                on = (phi >= arc.start) & ((phi <= arc.end) if last else (phi < arc.end))
                base[:, on] = arc.at(phi[on])
        return base + self.offset * normal

    @staticmethod
    def normals(phi: np.ndarray) -> np.ndarray:
        """(2, n) unit outward normals at turning angles ``phi``."""
        phi = np.asarray(phi, float)
        return np.stack([np.sin(phi), np.cos(phi)])

    def curvature(self, phi: np.ndarray) -> np.ndarray:
        """(n,) curvature (1/m) at turning angles ``phi`` (the offset's: 1 / (ρ + offset))."""
        phi = np.asarray(phi, float)
        if self.ellipse is not None:
            a, b = self.ellipse
            # radius of curvature of an ellipse at the normal angle φ: a²b² / h³
            rho = (a * b) ** 2 / np.hypot(a * np.sin(phi), b * np.cos(phi)) ** 3
        else:
            rho = np.empty(phi.size)
            for k, arc in enumerate(self.arcs):
                last = k == len(self.arcs) - 1
                on = (phi >= arc.start) & ((phi <= arc.end) if last else (phi < arc.end))
                rho[on] = arc.radius
        return 1.0 / (rho + self.offset)

    def arc_length(self, phi: np.ndarray, samples: int = 4001) -> np.ndarray:
        """(n,) length (m) along the profile from the crown to the turning angles ``phi``:
        ∫ρ dφ, exact per arc, by Simpson's rule on ``samples`` points for an ellipse."""
        phi = np.asarray(phi, float)
        if self.ellipse is None:
            out = np.zeros(phi.size)
            for arc in self.arcs:
                out += (arc.radius + self.offset) * np.clip(np.minimum(phi, arc.end) - arc.start, 0.0, None)
            return out
        grid = np.linspace(0.0, math.pi, samples)
        rho = 1.0 / self.curvature(grid)
        h = grid[1] - grid[0]
        cum = np.r_[0.0, np.cumsum(0.5 * h * (rho[1:] + rho[:-1]))]  # the trapezoid rule
        return np.interp(phi, grid, cum)

    def parameter(self, points: np.ndarray, iterations: int = 8) -> np.ndarray:
        """(n,) turning angles φ of the feet of the normals through ``points`` (2, n) (relative to
        the section's centre): the nearest of a fine sampling, refined by Newton's method on
        (P − C(φ))·T(φ) = 0, T = (cos φ, −sin φ) the tangent. For a point of the curve, its own φ;
        for a point of the lining, the φ of the normal cut it lies on."""
        from scipy.spatial import cKDTree

        points = np.asarray(points, float)
        grid = np.linspace(0.0, math.pi, 4097)
        phi = grid[cKDTree(self.points(grid).T).query(points.T)[1]]
        for _ in range(iterations):
            d = points - self.points(phi)
            tangent = np.stack([np.cos(phi), -np.sin(phi)])
            f = np.sum(d * tangent, axis=0)
            df = -1.0 / self.curvature(phi) - np.sum(d * self.normals(phi), axis=0)
            phi = np.clip(phi - f / df, 0.0, math.pi)
        return phi

    @property
    def length(self) -> float:
        """The half profile's length (m), crown to invert."""
        return float(self.arc_length(np.array([math.pi]))[0])

    def breaks(self) -> list[float]:
        """Turning angles (rad) where the curvature changes: the arcs' ends (tangent points)."""
        return [arc.end for arc in self.arcs[:-1]]

    def area(self) -> float:
        """Area (m²) the whole profile (both halves) encloses: 2 ∫ x dy along the half."""
        phi = np.linspace(0.0, math.pi, 20001)
        p = self.points(phi)
        return float(2.0 * np.trapezoid(p[0], -p[1]))


def polycentric(radii: list[float | None], angles_deg: list[float]) -> Profile:
    """The polycentric half profile of arcs (crown to invert) with ``radii`` (the last one solved
    by :func:`close_polycentric`; a given last radius must agree) and ``angles_deg``; centred on
    the point of the axis midway between crown and invert."""
    last = close_polycentric(radii, angles_deg)
    given = radii[-1]
    if given is not None and abs(given - last) > 1e-6 * last:
        raise SectionError(f"arcs.{len(radii) - 1}.radius",
                           f"{given:.9g} m does not close the profile; the closing radius is {last:.9g} m "
                           "(omit it to have it solved)")
    for i, r in enumerate(radii[:-1]):
        if r is None or not r > 0:
            raise SectionError(f"arcs.{i}.radius", "a positive radius (only the last arc's is solved)")
    radii = [*radii[:-1], last]
    phi = np.radians(np.r_[0.0, np.cumsum(angles_deg)])
    phi[-1] = math.pi
    arcs, x, y = [], 0.0, 0.0  # the crown at the origin first; the profile is moved to its centre below
    for r, a, b in zip(radii, phi[:-1], phi[1:]):
        c = (x - r * math.sin(a), y - r * math.cos(a))
        arcs.append(Arc(c, float(r), float(a), float(b)))
        x, y = c[0] + r * math.sin(b), c[1] + r * math.cos(b)
    mid = 0.5 * y  # the invert is at (0, y): the centre of section midway
    arcs = tuple(Arc((c[0], c[1] - mid), r, a, b) for (c, r, a, b) in
                 ((arc.center, arc.radius, arc.start, arc.end) for arc in arcs))
    profile = Profile(arcs=arcs)
    _check_half(profile, "arcs")
    return profile


def ellipse(width: float, height: float) -> Profile:
    """The elliptical half profile of the intrados ``width`` × ``height`` (m)."""
    return Profile(ellipse=(0.5 * width, 0.5 * height))


def circle(radius: float) -> Profile:
    """A circle of ``radius`` (m): one arc of 180°."""
    return Profile(arcs=(Arc((0.0, 0.0), float(radius), 0.0, math.pi),))


def three_centre_horseshoe(crown_radius: float, crown_angle: float, side_radius: float,
                           side_angle: float) -> tuple[list[float | None], list[float]]:
    """The polycentric arcs (radii, angles in deg) of a three-centre horseshoe: a crown arc, a side
    arc, and the invert arc (the rest of 180°, its radius solved for closure)."""
    invert = 180.0 - crown_angle - side_angle
    if not invert > 0:
        raise SectionError("side_angle", f"crown and side angles leave {invert:.6g} deg for the invert (> 0 needed)")
    return [crown_radius, side_radius, None], [crown_angle, side_angle, invert]


def _check_half(profile: Profile, field: str) -> None:
    """The half profile stays on its side of the axis (x > 0 between crown and invert)."""
    phi = np.linspace(0.0, math.pi, 2001)[1:-1]
    x = profile.points(phi)[0]
    if np.any(x <= 0.0):
        raise SectionError(field, "the profile crosses the symmetry axis between crown and invert")


def equal_area_radius(profile: Profile) -> float:
    """The radius (m) of the circle with the area the whole profile encloses."""
    return math.sqrt(profile.area() / math.pi)

"""Values a case accepts but a tunnel seldom has (issue 39, item 10): warnings, not refusals.

The case's bounds (:mod:`.canonical`, the fields' limits) refuse what is physically impossible;
these ranges flag what is possible but most likely a mistake of units, e.g. a ground density of
20 (a unit weight in kN/m³ typed where kg/m³ is asked: λ comes out a hundred times too small) or a
surface load of 100 (kPa typed where Pa is asked). Each warning names the field, the value, the
range and the likely slip.
"""
from __future__ import annotations

from dataclasses import dataclass

from .ground import hoek_brown_apex

__all__ = ["PLAUSIBLE", "plausibility_warnings"]


@dataclass(frozen=True)
class Range:
    """Plausible [low, high] in SI; ``zero`` also accepts 0 (an input that may be absent);
    ``unit`` and ``factor`` say it in the unit people read; ``hint`` the likely slip."""

    low: float
    high: float
    unit: str
    factor: float = 1.0
    zero: bool = False
    hint: str = ""


_DENSITY = "a unit weight in kN/m³ typed as a density? the field is kg/m³ (20 kN/m³ is about 2000 kg/m³)"
_STRESS = "kPa typed as Pa? the field is in Pa (100 kPa is 1e5)"
_MODULUS = "MPa or kPa typed as Pa? the field is in Pa (50 MPa is 5e7)"

#: Plausible ranges by field path; ground fields apply to every layer too.
PLAUSIBLE: dict[str, Range] = {
    "ground.density": Range(1000.0, 3000.0, "kg/m³", hint=_DENSITY),
    "ground.young": Range(1e6, 1.2e11, "MPa", 1e-6, hint=_MODULUS),
    "ground.poisson": Range(0.1, 0.49, ""),
    "ground.cohesion": Range(500.0, 5e7, "kPa", 1e-3, zero=True, hint=_STRESS),
    "ground.tensile_strength": Range(100.0, 2e7, "kPa", 1e-3, zero=True, hint=_STRESS),
    "ground.young_gradient": Range(1e4, 1e8, "MPa/m", 1e-6, zero=True, hint="the field is in Pa per metre"),
    "lining.density": Range(1000.0, 8000.0, "kg/m³", hint=_DENSITY),
    "lining.young": Range(1e9, 2.2e11, "MPa", 1e-6, hint=_MODULUS),
    "loads.surface_load": Range(1e3, 2e6, "kPa", 1e-3, zero=True, hint=_STRESS),
    "loads.lateral_ratio": Range(0.2, 3.0, ""),
    "water.unit_weight": Range(9500.0, 10500.0, "kN/m³", 1e-3, hint="the field is in N/m³ (9.81 kN/m³ is 9810)"),
    "design.reinforcement_area": Range(1e-4, 1e-2, "mm²/m", 1e6, zero=True,
                                       hint="the field is in m² per metre per face (1500 mm²/m is 1.5e-3)"),
    "design.load_factor": Range(1.0, 2.0, ""),
    "design.crack_width_limit": Range(0.05e-3, 0.5e-3, "mm", 1e3, hint="the field is in m (0.3 mm is 3e-4)"),
    "settlement.volume_loss": Range(5e-4, 0.05, "%", 100.0, hint="the field is a fraction (1 % is 0.01)"),
}
_GROUND = ("density", "young", "poisson", "cohesion", "tensile_strength", "young_gradient")


def _values(spec) -> list[tuple[str, float]]:
    """``(path, value)`` of every field with a range, layers by index; not a Hoek–Brown ground's
    default tension cut-off (its apex s σci / m_b, filled in: tens of Pa in weak rock, and not typed)."""
    out = []
    for path in PLAUSIBLE:
        section, field = path.split(".")
        value = getattr(getattr(spec, section), field)
        if value is not None and not (path == "ground.tensile_strength" and spec.ground.model == "hoek-brown"
                                      and hoek_brown_apex(spec.ground.model_dump()) == value):
            out.append((path, value))
    for i, layer in enumerate(spec.ground.layers):
        out += [(f"ground.layers.{i}.{field}", getattr(layer, field)) for field in _GROUND
                if getattr(layer, field, None) is not None]  # a field the layer leaves to the ground
    return out


#: The in-situ relative shear stress at the tunnel's axis from which a Mohr–Coulomb ground is near failure
#: (:func:`near_failure_warnings`).
NEAR_FAILURE = 0.85


def near_failure_warnings(spec) -> list[str]:
    """A sentence where the Mohr–Coulomb ground at the tunnel's axis already mobilizes :data:`NEAR_FAILURE`
    or more of its shear strength in situ: the relative shear stress ``τ/τ_max`` (PLAXIS's), ``τ`` the
    radius of the in-situ Mohr circle and ``τ_max`` that of the circle with its centre touching the
    Mohr–Coulomb line, ``c′ cos φ′ + p′ sin φ′``. Accepted (the state is inside the surface), but a wide
    zone then yields, up to the surface, the results are sensitive to K0 and c′, and the plastic solve is
    slow: in issue 36's seeded sample (docs/performance.md) the four cases at 0.88–0.90 cost 90–210 elastic
    ones, and none of the others reached 0.8."""
    import math

    import numpy as np

    from ..ground.strata import geostatic_state, layer_at, strata

    layers, z = strata(spec), spec.geometry.depth
    s = layers[int(layer_at(layers, np.array([z]))[0])]
    if s.model != "mohr-coulomb" or spec.excavation.method != "deconfinement":
        return []
    state = geostatic_state(spec, layers, np.array([z]))
    v, h = float(state["effective_v"][0]), float(state["effective_h"][0])
    phi = math.radians(s.friction_angle)
    strength = s.cohesion * math.cos(phi) + 0.5 * (v + h) * math.sin(phi)
    relative = 0.5 * abs(v - h) / strength if strength > 0 else math.inf
    if relative < NEAR_FAILURE:
        return []
    named = bool(spec.ground.layers)
    field = f"ground.layers.{s.index}.lateral_ratio" if named and spec.ground.layers[s.index].lateral_ratio \
        is not None else "loads.lateral_ratio"
    return [f"{field}: in situ the ground at the tunnel's axis ({z:.4g} m deep) already mobilizes {relative:.0%} of "
            f"its shear strength (K0 {s.k0:.4g}, c′ {s.cohesion / 1e3:.4g} kPa, φ′ {s.friction_angle:.4g}°): it is "
            "close to failure before the excavation, so a wide zone yields (up to the surface), the results are "
            "sensitive to K0 and c′, and the plastic solve takes long (tens of seconds to minutes)"]


def plausibility_warnings(spec) -> list[str]:
    """One sentence per field of the case :class:`~solver.spec.CaseSpec` ``spec`` outside its
    plausible range (:data:`PLAUSIBLE`), and one where the ground at the tunnel's axis is near failure
    in situ (:func:`near_failure_warnings`)."""
    warnings = near_failure_warnings(spec)
    for path, value in _values(spec):
        r = PLAUSIBLE[path if ".layers." not in path else "ground." + path.rsplit(".", 1)[1]]
        if (r.zero and value == 0) or r.low <= value <= r.high:
            continue
        unit = f" {r.unit}" if r.unit else ""
        shown = f"{value * r.factor:.4g}{unit}" + (f" ({value:.4g} as given)" if r.factor != 1.0 else "")
        text = (f"{path}: {shown} is outside the plausible range {r.low * r.factor:.4g} to "
                f"{r.high * r.factor:.4g}{unit}" + (" (or 0)" if r.zero else ""))
        warnings.append(text + (f"; {r.hint}" if r.hint else ""))
    return warnings

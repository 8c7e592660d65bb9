"""The units people read: results stored in SI (CF ``units``) are shown in engineering units
(kPa, kN/m, kN·m/m, mm) by every table, page, plot and workbook, through one table here.

Inputs keep the units of the case JSON (SPEC §1: SI); results are shown as below.
"""
from __future__ import annotations

import math

#: CF units of the results -> (unit shown to people, factor from SI).
DISPLAY_UNITS: dict[str, tuple[str, float]] = {
    "Pa": ("kPa", 1e-3), "N m-1": ("kN/m", 1e-3), "N m m-1": ("kN·m/m", 1e-3),
    "m": ("mm", 1e3), "degree": ("°", 1.0), "s": ("s", 1.0), "1": ("", 1.0),
    "m2": ("m²", 1.0), "m3 s-1": ("L/s per m", 1e3), "rad": ("mrad", 1e3),
}
#: Scalars that describe the solve rather than the tunnel (shown apart from the results).
DIAGNOSTICS = ("bolt_theta", "bolt_trials", "iterations", "converged", "kkt_residual", "solve_seconds")
#: Dimensionless results shown in per cent.
PERCENT = ("ground_loss", "volume_loss", "design_volume_loss")
#: Lengths read in metres (sizes of zones), not millimetres (displacements).
METRES = ("max_plastic_extent", "stage1_max_plastic_extent")


def display_unit(units: str, name: str | None = None) -> tuple[str, float]:
    """``(unit label, factor)`` to show a quantity stored in CF ``units`` (e.g. Pa -> kPa, 1e-3);
    ``name`` lets a dimensionless ratio be shown in per cent."""
    if name in PERCENT:
        return "%", 100.0
    if name in METRES:
        return "m", 1.0
    return DISPLAY_UNITS.get(units, (units, 1.0))


def shown_number(value, units: str | None, name: str | None = None, digits: int = 4) -> str:
    """``value`` in its display unit with ``digits`` significant digits, without the unit;
    ``-`` when missing or NaN, ``inf`` when infinite (the service sends inf as text or None)."""
    try:
        number = float(value)
    except (TypeError, ValueError):
        return "-"
    if math.isnan(number):
        return "-"
    if not math.isfinite(number):
        return "inf" if number > 0 else "-inf"
    return f"{number * display_unit(units or '', name)[1]:.{digits}g}"


def shown_value(value, units: str | None, name: str | None = None, digits: int = 4) -> str:
    """:func:`shown_number` followed by its unit (``"624.3 kN/m"``)."""
    text = shown_number(value, units, name, digits)
    unit = display_unit(units or "", name)[0]
    return f"{text} {unit}" if unit and text != "-" else text


def input_unit(name: str, units: str | None) -> tuple[str, float]:
    """``(unit label, factor from SI)`` in which people read and type input ``name`` (a flat
    parameter name, e.g. ``ground_young``): moduli and concrete/steel/rock strengths in MPa, other
    stresses in kPa, reinforcement in cm²/m; everything else as stored."""
    if units == "Pa":
        return ("MPa", 1e-6) if name.endswith(("young", "ucs")) or name.startswith("design_") else ("kPa", 1e-3)
    if units == "Pa m-1":
        return "MPa/m", 1e-6
    return {"m2 m-1": ("cm²/m", 1e4), "kg m-3": ("kg/m³", 1.0), "m s-2": ("m/s²", 1.0), "m s-1": ("m/s", 1.0),
            "degree": ("°", 1.0), "1": ("", 1.0)}.get(units or "", (units or "", 1.0))


#: Inputs read in millimetres (small lengths).
MILLIMETRE_INPUTS = ("geometry.gap", "design.crack_width_limit", "design.bar_diameter")


def parameter_unit(path: str, units: str | None, gravity: float | None = None) -> tuple[str, float]:
    """``(unit, factor from SI)`` in which every table, page and report shows input ``path`` (dotted) of
    CF ``units``: moduli and strengths in MPa, other stresses in kPa, small lengths in mm, other
    lengths in m, steel in mm²/m, fractions of a load or volume in %, and a density as the unit
    weight ρ g in kN/m³ when the case's ``gravity`` is given (kg/m³ otherwise)."""
    if path in MILLIMETRE_INPUTS:
        return "mm", 1e3
    if units == "kg m-3":
        return ("kN/m³", gravity * 1e-3) if gravity else ("kg/m³", 1.0)
    if units == "N m-3":
        return "kN/m³", 1e-3
    if units == "m2 m-1":
        return "mm²/m", 1e6
    if path.endswith(("volume_loss", "deconfinement")):
        return "%", 100.0
    unit, factor = input_unit(path.replace(".", "_"), units)
    return unit or "1", factor

"""The lining section's checks beside the N–M utilization (SPEC §9.3): shear (EN 1992-1-1 §6.2.2,
§12.6.3 for plain concrete) and the characteristic crack width (§7.3.4) against
``design.crack_width_limit``; one statement for the CLI, the report and the case page.

A plain section that cracks under the characteristic actions has no crack-width control (no bar
holds its cracks; §12 gives none): its crack width is stored as ``inf`` and it fails, saying why.
"""
from __future__ import annotations

import json
import math
from dataclasses import dataclass

import numpy as np
import xarray as xr

from solver.spec import Design

#: ``design.crack_width_limit`` of a case that does not give it (m).
DEFAULT_CRACK_LIMIT = Design.model_fields["crack_width_limit"].default


def crack_limit(spec) -> float:
    """``design.crack_width_limit`` (m) of a case spec (dict or canonical JSON text)."""
    if isinstance(spec, str):
        spec = json.loads(spec or "{}")
    return float(((spec or {}).get("design") or {}).get("crack_width_limit", DEFAULT_CRACK_LIMIT))


@dataclass(frozen=True)
class SectionCheck:
    """The largest shear utilization and crack width (m) of a lining and the crack width limit (m)."""

    shear: float
    crack: float
    limit: float

    @property
    def shear_passes(self) -> bool:
        return bool(self.shear <= 1.0)

    @property
    def crack_passes(self) -> bool:
        return bool(self.crack <= self.limit)

    @property
    def passes(self) -> bool:
        return self.shear_passes and self.crack_passes

    def text(self) -> str:
        """One line: shear η and w_k against their limits."""
        shear = (f"shear η = {self.shear:.3g} " + ("≤ 1" if self.shear_passes else "> 1")
                 + " (EN 1992-1-1 6.2.2 / 12.6.3)")
        if math.isinf(self.crack):
            crack = ("a plain section cracks under the characteristic actions: no crack-width control "
                     "(EN 1992-1-1 §12), fails")
        else:
            crack = (f"crack width w_k = {self.crack * 1e3:.3g} mm " + ("≤" if self.crack_passes else ">")
                     + f" {self.limit * 1e3:.3g} mm (7.3.4, characteristic actions)")
        return f"{shear}; {crack}"


def check_of(values: dict, spec) -> SectionCheck | None:
    """The check from a case's scalars (``max_shear_utilization``, ``max_crack_width``); None for a
    result made before these checks."""
    if "max_shear_utilization" not in values or "max_crack_width" not in values:
        return None
    return SectionCheck(float(values["max_shear_utilization"]), float(values["max_crack_width"]), crack_limit(spec))


def section_check(ds: xr.Dataset) -> SectionCheck | None:
    """The check of a stored result (None if it has no shear or crack width)."""
    if "shear_utilization" not in ds or "crack_width" not in ds:
        return None
    return SectionCheck(_largest(ds["shear_utilization"].values), _largest(ds["crack_width"].values),
                        crack_limit(ds.attrs.get("case_spec", "{}")))


def _largest(values: np.ndarray) -> float:
    checked = values[~np.isnan(values)]  # NaN at a segmental lining's joints
    return float(checked.max()) if checked.size else math.nan


def section_report(ds: xr.Dataset) -> str:
    """The checks in words with the stations where they are largest (empty if none)."""
    check = section_check(ds)
    if check is None:
        return ""
    theta = ds["theta"].values
    where = []
    for name, label in (("shear_utilization", "largest shear η"), ("crack_width", "widest crack")):
        values = ds[name].values
        if np.isnan(values).all():
            continue
        k = int(np.nanargmax(values))
        where.append(f"{label} at θ = {theta[k]:.1f}°")
    verdict = "passes" if check.passes else "fails"
    return f"section checks ({verdict}): {check.text()}\n  " + ", ".join(where)

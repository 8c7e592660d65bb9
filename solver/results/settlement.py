"""Settlements that mean something (SPEC §3): the ground loss at the excavation and the
empirical Gaussian trough of practice built from it, beside the FE surface.

Why both. A 2D linear elastic ground unloaded by the excavated weight rebounds: its surface
displacement far from the tunnel grows with the model's size (the default case settles a few
millimetres at its present size and heaves at eight times it), so the FE surface is a property
of the model as much as of the tunnel. The *ground loss* (the area by which the excavation
boundary closes in, over the excavated area) is set by the ground next to the tunnel and
hardly depends on where the model's walls are; the trough of practice (Peck 1969; O'Reilly &
New 1982) spreads that volume as ``S(x) = S_max exp(-x² / 2i²)`` with ``i = K z0``
(``K`` the trough width factor, 0.5 for clays, about 0.25-0.35 for sands; ``z0`` the axis
depth), so that ``√(2π) i S_max`` equals the ground loss times the excavated area.
"""
from __future__ import annotations

import numpy as np

#: Default trough width factor K (i = K z0): O'Reilly & New's value for clays.
TROUGH_WIDTH_FACTOR = 0.5


def ground_loss(u_ground: np.ndarray, ground_node: np.ndarray, normal: np.ndarray, weight: np.ndarray,
                hole_radius: float) -> float:
    """Area lost at the excavation boundary over the excavated area (1, both halves).

    ``u_ground`` (2, N) the ground's displacement since excavation; ``ground_node``,
    ``normal`` (the ground's outward normal, towards the tunnel axis) and ``weight`` (m, the
    boundary quadrature) of the interface. A rigid translation of the opening loses nothing.
    """
    inward = np.sum(u_ground[:, ground_node] * normal, axis=0)
    return float(np.sum(weight * inward) / (0.5 * np.pi * hole_radius**2))


def gaussian_trough(x: np.ndarray, loss: float, hole_radius: float, depth: float,
                    factor: float = TROUGH_WIDTH_FACTOR) -> tuple[np.ndarray, float]:
    """The Gaussian settlement trough (m, downward positive) at ``x`` (m from the tunnel's axis)
    holding the volume ``loss × π r²`` per metre, and its largest settlement ``S_max``."""
    i = factor * depth
    s_max = loss * np.pi * hole_radius**2 / (np.sqrt(2.0 * np.pi) * i)
    return s_max * np.exp(-np.asarray(x) ** 2 / (2.0 * i * i)), float(s_max)


def design_trough(x: np.ndarray, loss: float, hole_radius: float, depth: float, settlement) -> dict:
    """The design trough of SPEC §9.3 at ``x`` (m): ``settlement.volume_loss`` (None: ``loss``, the case's
    ground loss) spread with ``settlement.trough_width_factor`` K (i = K z0, z0 = ``depth``).

    Returns ``settlement`` (m, downward positive, shape of ``x``), ``max_settlement`` S_max (m),
    ``max_slope`` = S_max e^-½ / i (the largest |dS/dx| = (x/i²) S, at x = i) and
    ``max_horizontal_strain`` (1, tensile positive): O'Reilly & New's horizontal displacement
    x S(x)/z0 towards the axis gives ε_h = -(S/z0)(1 - x²/i²), compressive inside the inflection
    points and largest in tension at x = √3 i, 2 e^-3/2 S_max/z0 (at the axis, -S_max/z0, if the
    trough heaves).
    """
    volume = loss if settlement.volume_loss is None else settlement.volume_loss
    factor = settlement.trough_width_factor
    trough, s_max = gaussian_trough(x, volume, hole_radius, depth, factor)
    i = factor * depth
    return {"settlement": trough, "max_settlement": s_max, "volume_loss": float(volume),
            "max_slope": abs(s_max) * np.exp(-0.5) / i,
            "max_horizontal_strain": max(2.0 * np.exp(-1.5) * s_max, -s_max) / depth}


def surface_warnings(x: np.ndarray, settlement: np.ndarray) -> list[str]:
    """Why the FE surface settlement must not be read as the tunnel's trough: it heaves above
    the tunnel, or its largest settlement lies at the model's side boundary."""
    out = []
    reach = float(np.max(np.abs(settlement))) if settlement.size else 0.0
    if settlement[0] < -1e-9 * max(reach, 1e-300):
        out.append(f"the FE ground surface heaves {-1e3 * settlement[0]:.3g} mm above the tunnel")
    if settlement.size > 1 and int(np.argmax(settlement)) == settlement.size - 1 and settlement[-1] > 0:
        out.append(f"the FE surface's largest settlement ({1e3 * settlement[-1]:.3g} mm) lies at the model's "
                   f"side boundary (x = {x[-1]:.4g} m)")
    if out:
        out[-1] += ("; in 2D elastic ground the surface displacement grows with the model's size (the excavated "
                    "weight's removal lifts it), so assess settlement on the Gaussian trough from the ground loss")
    return out


def with_trough_width(ds, factor: float):
    """A copy of a case result whose Gaussian trough uses the trough width factor ``factor``
    (``gaussian_settlement`` and ``gaussian_max_settlement`` recomputed from its ground loss;
    e.g. 0.3 for a sand instead of the default 0.5)."""
    import json

    if not 0.05 <= factor <= 2.0:
        raise ValueError(f"trough_width_factor: {factor} is outside [0.05, 2]")
    spec = json.loads(ds.attrs["case_spec"])
    geometry = {"inner_radius": 2.5, "thickness": 0.3, "gap": 0.0, "depth": 15.0, **spec.get("geometry", {})}
    radius = geometry["inner_radius"] + geometry["thickness"] + geometry["gap"]
    trough, s_max = gaussian_trough(ds["surface_x"].values, float(ds["ground_loss"]), radius,
                                    geometry["depth"], factor)
    out = ds.copy()
    out["gaussian_settlement"] = out["gaussian_settlement"].copy(data=trough)
    out["gaussian_settlement"].attrs.update(trough_width_factor=factor, trough_width_m=factor * geometry["depth"])
    out["gaussian_max_settlement"] = out["gaussian_max_settlement"].copy(data=s_max)
    return out

"""The ground as strata: each layer's properties and its geostatic state (SPEC §1.4).

Plain functions of a :class:`~solver.spec.CaseSpec`. Depth ``z`` is measured down from the
surface (``z = -y``), stresses are compression positive here (as ``σv`` and ``u`` are spoken
of); callers turn them into the result's tension-positive components.
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from .hoek_brown import hoek_brown_excess

__all__ = ["Stratum", "strata", "layer_lines", "table_line", "mesh_lines", "moved_lines", "layer_at", "geostatic_state", "geostatic_profile"]


@dataclass(frozen=True)
class Stratum:
    """One layer, every property resolved (a one-layer ground is ``ground`` itself).

    top, bottom : m, depths below the surface (the last layer's bottom is the model's).
    young : Pa at the layer's top; young_gradient : Pa/m below it; k0 : σ′h/σ′v.
    """

    index: int
    top: float
    bottom: float
    young: float
    poisson: float
    density: float
    k0: float
    young_gradient: float
    permeability: float
    model: str
    cohesion: float
    friction_angle: float
    dilatancy: float
    tensile_strength: float
    ucs: float = 0.0
    gsi: float = 0.0
    mi: float = 0.0
    disturbance: float = 0.0

    def young_at(self, z: np.ndarray) -> np.ndarray:
        """E (Pa) at depths ``z`` (m) inside the layer."""
        return self.young + self.young_gradient * (np.asarray(z, dtype=float) - self.top)


#: A layer line nearer the excavation's crown or invert level than this many interface sizes is
#: moved to that distance from it, outside the excavation: a line (nearly) tangent to the
#: tunnel would leave the mesh a wedge of vanishing angle there.
TANGENT_CLEARANCE = 0.5


def layer_lines(spec) -> list[float]:
    """Depths (m) of the lines between layers as the mesh draws them, from the surface down.

    A line within :data:`TANGENT_CLEARANCE` interface sizes of the level of the excavation's
    crown or invert is moved to that distance from it, away from the excavation (see
    :func:`moved_lines`); every other line lies where the layers put it."""
    g = spec.geometry
    layers = spec.ground.layers
    up, down, _ = g.hole_extent  # the hole radius for a circle
    crown, invert = g.depth - up, g.depth + down
    clear = TANGENT_CLEARANCE * spec.mesh.interface_size
    lines, z = [], 0.0
    for layer in layers[:-1]:
        z += layer.thickness
        if abs(z - crown) < clear:
            z_mesh = crown - clear
        elif abs(z - invert) < clear:
            z_mesh = invert + clear
        else:
            z_mesh = z
        if z_mesh <= (lines[-1] if lines else 0.0) + 1e-9 * g.height:
            raise ValueError(
                f"ground.layers.{len(lines)}.thickness: the layer is too thin to be drawn where a layer line "
                f"meets the tunnel's crown or invert level ({z:.6g} m; lines within {clear:.3g} m of that "
                "level are moved to that distance)")
        lines.append(z_mesh)
    return lines


def table_line(spec) -> float | None:
    """Depth (m) of a drained case's water table as a mesh line (SPEC §9.2), or None.

    The hydrostatic pore pressure has a kink at the table and a drained lining's seepage starts
    from it: a line of the mesh there puts the kink on element edges. None for other cases
    (their mesh is the layers' alone), for a table at the surface or below the model, on a
    layer line already, or within :data:`TANGENT_CLEARANCE` interface sizes of the excavation's
    crown or invert level or of a layer line (a wedge of vanishing angle): there the kink stays
    inside the elements it crosses."""
    w, g = spec.water, spec.geometry
    if w.table is None or w.lining != "drained" or not 0.0 < w.table < g.height:
        return None
    clear = TANGENT_CLEARANCE * spec.mesh.interface_size
    up, down, _ = g.hole_extent
    near = [g.depth - up, g.depth + down, *layer_lines(spec)]
    if any(abs(w.table - z) < clear for z in near):
        return None
    return float(w.table)


def mesh_lines(spec) -> list[float]:
    """Depths (m) of every horizontal line of the ground's mesh, from the surface down: the layer
    lines (:func:`layer_lines`) and a drained case's water table (:func:`table_line`)."""
    lines = layer_lines(spec)
    table = table_line(spec)
    return lines if table is None else sorted([*lines, table])


def band_layers(spec) -> np.ndarray:
    """The layer of each band of the ground's mesh between consecutive :func:`mesh_lines`."""
    lines = mesh_lines(spec)
    edges = np.r_[0.0, lines, spec.geometry.height]
    middle = 0.5 * (edges[:-1] + edges[1:])
    if not spec.ground.layers:
        return np.zeros(middle.size, np.int64)
    return layer_at(strata(spec), middle)


def moved_lines(spec) -> list[tuple[int, float, float]]:
    """``(layer, given depth, drawn depth)`` of each layer top that :func:`layer_lines` moved."""
    out, z = [], 0.0
    for i, (layer, drawn) in enumerate(zip(spec.ground.layers[:-1], layer_lines(spec))):
        z += layer.thickness
        if drawn != z:
            out.append((i + 1, z, drawn))
    return out


def strata(spec) -> list[Stratum]:
    """The case's layers from the surface down (one layer of ``ground`` when none are given),
    bounded by the lines the mesh draws (:func:`layer_lines`)."""
    g, height, k0 = spec.ground, spec.geometry.height, spec.loads.lateral_ratio
    layers = g.layers or (g,)
    lines = layer_lines(spec) if g.layers else []
    out, top = [], 0.0
    for i, layer in enumerate(layers):
        last = i == len(layers) - 1
        bottom = height if last else lines[i]
        lr = getattr(layer, "lateral_ratio", None)
        out.append(Stratum(
            index=i, top=top, bottom=bottom, young=layer.young, poisson=layer.poisson, density=layer.density,
            k0=k0 if lr is None else lr, young_gradient=layer.young_gradient, permeability=layer.permeability,
            model=layer.model, cohesion=layer.cohesion, friction_angle=layer.friction_angle,
            dilatancy=layer.dilatancy, tensile_strength=layer.tensile_strength, ucs=layer.ucs, gsi=layer.gsi,
            mi=layer.mi, disturbance=layer.disturbance))
        top = bottom
    return out


def layer_at(layers: list[Stratum], z: np.ndarray) -> np.ndarray:
    """Index of the layer holding each depth ``z`` (a depth on a boundary belongs to the layer below)."""
    tops = np.array([s.top for s in layers[1:]])
    return np.searchsorted(tops, np.asarray(z, dtype=float), side="right")


def geostatic_state(spec, layers: list[Stratum], z: np.ndarray, layer: np.ndarray | None = None) -> dict:
    """In-situ state at depths ``z`` (m), compression positive (Pa).

    ``layer`` picks the layer of each point (e.g. the layer of its element, so that K0 jumps
    where the mesh's layer line is); by default :func:`layer_at`. Returns ``sigma_v`` (total
    vertical), ``pore`` (hydrostatic pore pressure, 0 above the table or in dry ground),
    ``effective_v``, ``effective_h`` (K0 of the layer times ``effective_v``) and ``sigma_h``.
    """
    z = np.asarray(z, dtype=float)
    idx = layer_at(layers, z) if layer is None else np.asarray(layer)
    L, gravity = spec.loads, spec.loads.gravity
    tops = np.array([s.top for s in layers])
    rho = np.array([s.density for s in layers])
    # total vertical stress: the surcharge and the weight of every layer above, then this one's
    above = np.r_[0.0, np.cumsum(rho[:-1] * gravity * np.diff(np.r_[tops, layers[-1].bottom])[:-1])]
    sigma_v = L.surface_load + above[idx] + rho[idx] * gravity * (z - tops[idx])
    table = spec.water.table
    pore = np.zeros_like(z) if table is None else spec.water.unit_weight * np.maximum(z - table, 0.0)
    eff_v = sigma_v - pore
    eff_h = np.array([s.k0 for s in layers])[idx] * eff_v
    return {"sigma_v": sigma_v, "pore": pore, "effective_v": eff_v, "effective_h": eff_h, "sigma_h": eff_h + pore}


def geostatic_profile(spec, layers: list[Stratum]):
    """``(layer, depth, state)`` at every layer's top, bottom and (inside it) the water table:
    the in-situ state is linear in depth between these points, so checks of it there hold
    everywhere (a convex yield function, for one)."""
    table = spec.water.table
    for s in layers:
        depths = [s.top, s.bottom]
        if table is not None and s.top < table < s.bottom:
            depths.insert(1, table)
        for z in depths:
            state = geostatic_state(spec, layers, np.array([z]), np.array([s.index]))
            yield s, z, {k: float(v[0]) for k, v in state.items()}


def mohr_coulomb_excess(s_major: float, s_minor: float, cohesion: float, friction_angle: float,
                        tensile_strength: float = 0.0) -> float:
    """How far a state with major and minor principal stresses (Pa, compression positive) lies
    outside the Mohr–Coulomb surface with its tension cut-off (Pa; ≤ 0 inside)."""
    phi = np.radians(friction_angle)
    shear = (s_major - s_minor) - (s_major + s_minor) * np.sin(phi) - 2.0 * cohesion * np.cos(phi)
    return float(max(shear, -s_minor - tensile_strength))


def geostatic_errors(spec, layers: list[Stratum]) -> list[tuple[str, str]]:
    """``(field, reason)`` for each layer whose in-situ effective stress is tensile (a ground lighter
    than water below the table: its skeleton would float, elastic or not) and each yielding layer
    whose in-situ state lies outside its yield surface."""
    errors = []
    named = bool(spec.ground.layers)
    table, gamma_w = spec.water.table, spec.water.unit_weight
    for s in layers:
        if table is not None and s.bottom > table and s.density * spec.loads.gravity < gamma_w:
            errors.append((f"ground.layers.{s.index}.density" if named else "ground.density",
                           f"{s.density:.4g} kg/m3 is lighter than water below the water table (unit weight "
                           f"{s.density * spec.loads.gravity:.4g} < {gamma_w:.4g} N/m3): the effective stress "
                           f"would fall with depth (tension) and the ground must be heavier than water"))
    if errors:
        return errors
    for s, z, st in geostatic_profile(spec, layers):
        v, h = st["effective_v"], st["effective_h"]
        prefix = f"ground.layers.{s.index}." if named else ""
        if v < -1e-9 * max(1.0, st["sigma_v"]):
            errors.append((prefix + "density" if named else "ground.density",
                           f"the effective vertical stress is {v:.4g} Pa (tension) at {z:.4g} m depth"))
            continue
        if s.model == "hoek-brown":
            excess = hoek_brown_excess(max(v, h), min(v, h), s.ucs, s.gsi, s.mi, s.disturbance, s.tensile_strength)
            if excess > 1e-9 * max(abs(v), abs(h), 1.0):
                field = prefix + "lateral_ratio" if named and spec.ground.layers[s.index].lateral_ratio is not None \
                    else "loads.lateral_ratio"
                errors.append((field, f"K0 = {s.k0:.4g} puts the in-situ state of layer {s.index} outside its "
                                      f"Hoek-Brown surface at {z:.4g} m depth (sigma'v = {v:.4g} Pa, "
                                      f"sigma'h = {h:.4g} Pa; ucs = {s.ucs:.4g} Pa, GSI = {s.gsi:.4g}, "
                                      f"mi = {s.mi:.4g}, D = {s.disturbance:.4g})"))
            continue
        if s.model != "mohr-coulomb":
            continue
        scale = max(abs(v), abs(h), s.cohesion, 1.0)
        if mohr_coulomb_excess(max(v, h), min(v, h), s.cohesion, s.friction_angle, s.tensile_strength) \
                > 1e-9 * scale:
            field = prefix + "lateral_ratio" if named and spec.ground.layers[s.index].lateral_ratio is not None \
                else "loads.lateral_ratio"
            errors.append((field, f"K0 = {s.k0:.4g} puts the in-situ state of layer {s.index} outside its "
                                  f"Mohr-Coulomb surface at {z:.4g} m depth (sigma'v = {v:.4g} Pa, "
                                  f"sigma'h = {h:.4g} Pa; c = {s.cohesion:.4g} Pa, phi = {s.friction_angle:.4g} deg)"))
    return errors

"""The ground's parts of a case: its material, its strength when it yields, its layers."""
from __future__ import annotations

import math
from typing import Literal, Optional

from pydantic import Field, field_validator, model_validator

from .canonical import (MAX_DENSITY, MAX_FRICTION_ANGLE, MAX_LAYERS, MAX_PERMEABILITY, MAX_POISSON, MAX_YOUNG,
                        MIN_PERMEABILITY, MIN_YOUNG, _first_message, _Frozen, _ignorable)


class Material(_Frozen):
    """Isotropic linear elastic material (plane strain)."""

    young: float = Field(ge=MIN_YOUNG, le=MAX_YOUNG, description="Young's modulus E (Pa)")
    poisson: float = Field(ge=0, le=MAX_POISSON, description="Poisson ratio")
    density: float = Field(ge=0, le=MAX_DENSITY, description="mass density (kg/m^3)")


class Strength(_Frozen):
    """Mohr–Coulomb strength and flow (SPEC §1.5) and the stiffness gradient and permeability of
    §1.4: the round-3 fields shared by the ground and each of its layers."""

    model: Literal["elastic", "mohr-coulomb", "hoek-brown"] = Field(
        "elastic", description="'elastic', 'mohr-coulomb' or 'hoek-brown' (generalized, 2002; elastic-perfectly "
                               "plastic)")
    cohesion: float = Field(0.0, ge=0, le=1.0e9, description="Mohr-Coulomb cohesion c (Pa)")
    friction_angle: float = Field(30.0, ge=0, le=MAX_FRICTION_ANGLE, description="friction angle phi (deg)")
    dilatancy: float = Field(0.0, ge=0, le=MAX_FRICTION_ANGLE, description="dilatancy angle psi (deg), 0 <= psi <= phi")
    tensile_strength: float = Field(0.0, ge=0, le=1.0e9, description="tension cut-off (Pa), at most c cot(phi); "
                                    "Hoek-Brown: at most s ucs / m_b, its default")
    ucs: float = Field(0.0, ge=0, le=1.0e10, description="Hoek-Brown: uniaxial compressive strength of the intact "
                                                          "rock sigma_ci (Pa)")
    gsi: float = Field(0.0, ge=0, le=100.0, description="Hoek-Brown: geological strength index GSI (10-100)")
    mi: float = Field(0.0, ge=0, le=50.0, description="Hoek-Brown: intact rock constant m_i (1-50)")
    disturbance: float = Field(0.0, ge=0, le=1.0, description="Hoek-Brown: disturbance factor D (0-1)")
    young_gradient: float = Field(
        0.0, ge=0, le=1.0e10, description="increase of E with depth below the layer's top (Pa/m)")
    permeability: float = Field(
        1.0e-6, ge=MIN_PERMEABILITY, le=MAX_PERMEABILITY, description="hydraulic conductivity k (m/s)")

    @model_validator(mode="before")
    @classmethod
    def _strength_only_when_plastic(cls, data):
        # a ground ignores the strength of the laws it does not follow: one physical case, one id
        if not isinstance(data, dict):
            return data
        model = data.get("model", "elastic")
        ignored = {"elastic": {**STRENGTH_DEFAULTS, **HOEK_BROWN_DEFAULTS}, "mohr-coulomb": HOEK_BROWN_DEFAULTS,
                   "hoek-brown": MOHR_COULOMB_ONLY}.get(model, {})
        data = {**data, **{k: v for k, v in ignored.items() if k not in data or _ignorable(data[k])}}
        if model == "hoek-brown" and data.get("tensile_strength") is None:
            data["tensile_strength"] = hoek_brown_apex(data)  # SPEC §9.1: s ucs / m_b by default
        return data

    @model_validator(mode="after")
    def _strength(self):
        if self.model == "hoek-brown":
            return self._hoek_brown()
        if self.model != "mohr-coulomb":
            return self
        if self.dilatancy > self.friction_angle:
            raise ValueError(f"dilatancy: {self.dilatancy} deg exceeds the friction angle "
                             f"({self.friction_angle} deg); 0 <= psi <= phi")
        if self.cohesion <= 0 and self.friction_angle <= 0:
            raise ValueError("cohesion: a Mohr-Coulomb ground needs cohesion > 0 or friction_angle > 0")
        if self.friction_angle > 0:
            apex = self.cohesion / math.tan(math.radians(self.friction_angle))
            if self.tensile_strength > apex * (1 + 1e-12):
                raise ValueError(f"tensile_strength: {self.tensile_strength:.6g} Pa exceeds c cot(phi) = "
                                 f"{apex:.6g} Pa, the apex of the Mohr-Coulomb cone")
        return self


    def _hoek_brown(self):
        from ..ground.hoek_brown import parameter_errors

        errors = parameter_errors(self.ucs, self.gsi, self.mi, self.disturbance, self.dilatancy,
                                  self.tensile_strength)
        if errors:
            field, reason = next(iter(errors.items()))
            raise ValueError(f"{field}: {reason} for a Hoek-Brown ground")
        return self


def hoek_brown_apex(data: dict) -> float:
    """The default tension cut-off s ucs / m_b of a Hoek–Brown ground's ``data`` (0.0 when its
    constants are missing or out of range: the after-validator names the field)."""
    from ..ground.hoek_brown import default_tensile_strength, parameter_errors

    values = [data.get(k, HOEK_BROWN_DEFAULTS[k]) for k in ("ucs", "gsi", "mi", "disturbance")]
    if parameter_errors(*values):
        return 0.0
    return float(default_tensile_strength(*values))


#: Round-3 strength fields at their defaults (what an elastic ground records).
STRENGTH_DEFAULTS = {"cohesion": 0.0, "friction_angle": 30.0, "dilatancy": 0.0, "tensile_strength": 0.0}
#: Round-4 Hoek–Brown fields at their defaults (what a ground of another law records, SPEC §9.1).
HOEK_BROWN_DEFAULTS = {"ucs": 0.0, "gsi": 0.0, "mi": 0.0, "disturbance": 0.0}
#: What only Mohr–Coulomb reads (a Hoek–Brown ground records the defaults).
MOHR_COULOMB_ONLY = {"cohesion": 0.0, "friction_angle": 30.0}


class Layer(_Frozen):
    """One horizontal stratum (SPEC §1.4): a field it omits takes the ``ground`` value (filled
    by :class:`Ground`, so the canonical JSON states every layer in full)."""

    thickness: float = Field(0.0, ge=0, le=10000.0, description="layer thickness (m); the last layer's is ignored")
    young: Optional[float] = Field(None, ge=MIN_YOUNG, le=MAX_YOUNG, description="Young's modulus at the layer's top (Pa)")
    poisson: Optional[float] = Field(None, ge=0, le=MAX_POISSON, description="Poisson ratio")
    density: Optional[float] = Field(None, ge=0, le=MAX_DENSITY, description="bulk density (kg/m^3; saturated below the table)")
    lateral_ratio: Optional[float] = Field(None, ge=0, le=10.0, description="K0 of the layer (default loads.lateral_ratio)")
    young_gradient: Optional[float] = Field(None, ge=0, le=1.0e10, description="increase of E with depth (Pa/m)")
    permeability: Optional[float] = Field(None, ge=MIN_PERMEABILITY, le=MAX_PERMEABILITY, description="k (m/s)")
    model: Optional[Literal["elastic", "mohr-coulomb", "hoek-brown"]] = None
    cohesion: Optional[float] = Field(None, ge=0, le=1.0e9, description="cohesion c (Pa)")
    friction_angle: Optional[float] = Field(None, ge=0, le=MAX_FRICTION_ANGLE, description="friction angle (deg)")
    dilatancy: Optional[float] = Field(None, ge=0, le=MAX_FRICTION_ANGLE, description="dilatancy angle (deg)")
    tensile_strength: Optional[float] = Field(None, ge=0, le=1.0e9, description="tension cut-off (Pa)")
    ucs: Optional[float] = Field(None, ge=0, le=1.0e10, description="Hoek-Brown sigma_ci (Pa)")
    gsi: Optional[float] = Field(None, ge=0, le=100.0, description="Hoek-Brown GSI")
    mi: Optional[float] = Field(None, ge=0, le=50.0, description="Hoek-Brown m_i")
    disturbance: Optional[float] = Field(None, ge=0, le=1.0, description="Hoek-Brown D")


#: The fields a layer inherits from ``ground`` (``lateral_ratio`` from ``loads``).
LAYER_FIELDS = ("young", "poisson", "density", "young_gradient", "permeability", "model", "cohesion",
                "friction_angle", "dilatancy", "tensile_strength", "ucs", "gsi", "mi", "disturbance")


class Ground(Material, Strength):
    young: float = Field(5.0e7, ge=MIN_YOUNG, le=MAX_YOUNG, description="ground Young's modulus (Pa)")
    poisson: float = Field(0.3, ge=0, le=MAX_POISSON, description="ground Poisson ratio")
    density: float = Field(2000.0, ge=0, le=MAX_DENSITY, description="ground density (kg/m^3)")
    layers: tuple[Layer, ...] = Field(
        (), max_length=MAX_LAYERS, description="horizontal strata from the surface down (empty: one layer of ground)")

    @field_validator("layers", mode="before")
    @classmethod
    def _layers_list(cls, v):
        return tuple(v) if isinstance(v, list) else v  # a JSON list (strict mode takes tuples only)

    @model_validator(mode="after")
    def _fill_layers(self) -> "Ground":
        # every layer states every field, so one physical case has one canonical JSON
        filled = []
        for i, layer in enumerate(self.layers):
            given = {k: v for k, v in layer.model_dump().items() if v is not None}
            values = {k: getattr(self, k) for k in LAYER_FIELDS} | given
            if values["model"] == "hoek-brown" and "tensile_strength" not in given \
                    and (self.model != "hoek-brown" or given.keys() & HOEK_BROWN_DEFAULTS.keys()):
                values.pop("tensile_strength")  # its own constants' apex, not the ground's cut-off
            try:
                strength = Strength.model_validate({k: values[k] for k in Strength.model_fields if k in values})
            except ValueError as exc:  # the layer's own strength checks, named by its index
                raise ValueError(f"layers.{i}.{_first_message(exc)}") from None
            values |= {k: getattr(strength, k) for k in (*STRENGTH_DEFAULTS, *HOEK_BROWN_DEFAULTS)}
            filled.append(Layer.model_validate(values | {"thickness": layer.thickness,
                                                         "lateral_ratio": given.get("lateral_ratio")}))
        for i, layer in enumerate(filled[:-1]):
            if layer.thickness <= 0:
                raise ValueError(f"layers.{i}.thickness: must be > 0 (only the last layer, which reaches "
                                 "the model's bottom, may give none)")
        if filled:  # the last layer's thickness is ignored: recorded as 0
            filled[-1] = filled[-1].model_copy(update={"thickness": 0.0})
        object.__setattr__(self, "layers", tuple(filled))
        return self

"""``geometry.section`` (SPEC §9.4): the intrados's shape, and its expansion to a profile."""
from __future__ import annotations

from typing import Literal, Optional

from pydantic import Field, field_validator, model_validator

from ..geometry.section import Profile, SectionError, circle, ellipse, polycentric, three_centre_horseshoe
from .canonical import _Frozen

#: Template fields of the three-centre horseshoe (expanded to ``polycentric``).
HORSESHOE_FIELDS = ("crown_radius", "crown_angle", "side_radius", "side_angle")


class ArcSpec(_Frozen):
    """One arc of a polycentric intrados, crown to invert."""

    radius: Optional[float] = Field(None, gt=0, le=100.0, description="radius (m); the last arc's is solved")
    angle: float = Field(gt=0, le=180.0, description="angle the arc turns through (deg)")


class Section(_Frozen):
    """The intrados: ``circle`` (radius ``geometry.inner_radius``), ``ellipse`` (``width`` ×
    ``height``), ``polycentric`` (``arcs``), or the template ``horseshoe`` (crown and side
    radii and angles, the invert's radius solved), stored as the ``polycentric`` it expands to."""

    shape: Literal["circle", "ellipse", "polycentric", "horseshoe"] = "circle"
    width: Optional[float] = Field(None, gt=0, le=100.0, description="ellipse: intrados width (m)")
    height: Optional[float] = Field(None, gt=0, le=100.0, description="ellipse: intrados height (m)")
    arcs: tuple[ArcSpec, ...] = Field((), max_length=12, description="polycentric: arcs from crown to invert")
    crown_radius: Optional[float] = Field(None, gt=0, le=100.0, description="horseshoe: crown arc radius (m)")
    crown_angle: Optional[float] = Field(None, gt=0, lt=180.0, description="horseshoe: crown arc angle (deg)")
    side_radius: Optional[float] = Field(None, gt=0, le=100.0, description="horseshoe: side arc radius (m)")
    side_angle: Optional[float] = Field(None, gt=0, lt=180.0, description="horseshoe: side arc angle (deg)")

    @field_validator("arcs", mode="before")
    @classmethod
    def _arcs_list(cls, v):
        return tuple(v) if isinstance(v, list) else v  # a JSON list (strict mode takes tuples only)

    @model_validator(mode="before")
    @classmethod
    def _expand_template(cls, data):
        if not isinstance(data, dict) or data.get("shape") != "horseshoe":
            return data
        missing = [k for k in HORSESHOE_FIELDS if data.get(k) is None]
        if missing:
            raise ValueError(f"{missing[0]}: the horseshoe template needs {', '.join(HORSESHOE_FIELDS)}")
        extra = sorted(set(data) - {"shape", *HORSESHOE_FIELDS})
        if extra:
            raise ValueError(f"{extra[0]}: not a field of the horseshoe template")
        try:
            radii, angles = three_centre_horseshoe(*(data[k] for k in HORSESHOE_FIELDS))
        except SectionError as exc:
            raise ValueError(str(exc)) from None
        except TypeError:  # a field of the wrong type: let field validation name it
            return data
        return {"shape": "polycentric", "arcs": [{"radius": r, "angle": a} for r, a in zip(radii, angles)]}

    @model_validator(mode="after")
    def _closes(self) -> "Section":
        used = {"circle": (), "ellipse": ("width", "height"), "polycentric": ("arcs",)}[self.shape]
        for name in ("width", "height", "arcs", *HORSESHOE_FIELDS):
            if name not in used and getattr(self, name) not in (None, ()):
                raise ValueError(f"{name}: not a field of a '{self.shape}' section")
        for name in used:
            if getattr(self, name) in (None, ()):
                raise ValueError(f"{name}: required for a '{self.shape}' section")
        if self.shape == "polycentric":
            try:
                polycentric([a.radius for a in self.arcs], [a.angle for a in self.arcs])
            except SectionError as exc:
                raise ValueError(str(exc)) from None
            # one form per profile: the last radius is the solved one, so it is not stored
            last = self.arcs[-1].model_copy(update={"radius": None})
            object.__setattr__(self, "arcs", (*self.arcs[:-1], last))
        return self

    def profile(self, inner_radius: float) -> Profile:
        """The intrados as a :class:`~solver.geometry.section.Profile` (``inner_radius``: the
        circle's radius)."""
        if self.shape == "circle":
            return circle(inner_radius)
        if self.shape == "ellipse":
            return ellipse(self.width, self.height)
        return polycentric([a.radius for a in self.arcs], [a.angle for a in self.arcs])

"""One form per number and one id per case: the canonical JSON a case's id hashes, the frozen
base of every part of a case, and the physical bounds its fields are checked against."""
from __future__ import annotations

import hashlib
import json
import math
import sys

from pydantic import BaseModel, ConfigDict, field_validator

#: Physical bounds, wide but real: soft soil to steel, and a Poisson ratio far enough
#: below 1/2 that plane-strain elasticity stays well conditioned (volumetric locking).
MIN_YOUNG, MAX_YOUNG = 1.0e5, 1.0e12
MAX_POISSON = 0.49
MAX_DENSITY = 2.0e4
#: Friction and dilatancy angles (deg), permeability (m/s) and number of strata accepted.
MAX_FRICTION_ANGLE = 70.0
MIN_PERMEABILITY, MAX_PERMEABILITY = 1.0e-13, 1.0e-1
MAX_LAYERS = 20
MAX_SEGMENTS = 24
#: Largest lining / ground stiffness ratio the factorization and contact solve handle.
MAX_STIFFNESS_RATIO = 1.0e6


def canonical_json(model: BaseModel, exclude=None) -> str:
    """Defaults filled, keys sorted, no whitespace: the text a model's id hashes; less the fields of
    ``exclude`` (as pydantic's ``model_dump`` takes it: what a solve kept by it does not depend on)."""
    return json.dumps(model.model_dump(mode="json", exclude=exclude), sort_keys=True, separators=(",", ":"))


def content_id(text: str) -> str:
    """Stable 16-hex-digit id of a canonical text (first digits of its sha256)."""
    return hashlib.sha256(text.encode()).hexdigest()[:16]


def is_number(value) -> bool:
    """Whether ``value`` is a number as JSON has them (a bool is not one)."""
    return isinstance(value, (int, float)) and not isinstance(value, bool)


def _first_message(exc: Exception) -> str:
    """``field: reason`` of the first error of a validation error (named as :mod:`solver.errors` names it)."""
    from ..errors import field_errors

    errors = field_errors(exc) if hasattr(exc, "errors") else [("", str(exc))]
    field, reason = errors[0]
    return f"{field}: {reason}" if field else reason


def _ignorable(value) -> bool:
    """Whether ``value`` of a field its model ignores may be replaced by the canonical one: a
    finite number (anything else is left for validation to refuse)."""
    return is_number(value) and math.isfinite(value)


def canonical_number(value):
    """``value`` with one form per number: ``-0.0`` is ``0.0`` (one case, one id); a subnormal
    float (below 2.2e-308 in magnitude, e.g. 5e-324) is refused: no physical input is that
    small, and dividing by one overflows. Anything else is returned unchanged."""
    if isinstance(value, float):
        if value == 0.0:
            return 0.0
        if math.isfinite(value) and abs(value) < sys.float_info.min:
            raise ValueError(f"{value!r} is a subnormal number (below {sys.float_info.min:.3g} in magnitude); "
                             "give 0 or a physical value")
    return value


class _Frozen(BaseModel):
    # allow_inf_nan=False: NaN, Infinity and overflowing literals such as 1e400 are
    # refused with the field's name instead of failing later in the solver.
    # strict: a number is a number. Lax validation took JSON ``true`` as 1.0 (a 1 m
    # lining) and the string "0.5" as 0.5; an integer field takes integers only.
    model_config = ConfigDict(frozen=True, extra="forbid", allow_inf_nan=False, strict=True)

    @field_validator("*", mode="before")
    @classmethod
    def _one_form_per_number(cls, value):
        return canonical_number(value)

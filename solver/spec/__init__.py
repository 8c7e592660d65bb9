"""The case model: every input of one tunnel-contact computation (SPEC §2).

A :class:`CaseSpec` is immutable, rejects unknown fields, has a default for every
value (``CaseSpec()`` is the default case) and checks physical sense with
messages that start with the dotted path of the offending field, e.g.
``geometry.depth: cover above the tunnel is -0.2 m; ...``. Its parts: the canonical forms
and bounds (:mod:`.canonical`), the ground (:mod:`.ground`), the other sections
(:mod:`.parts`) and the case itself (:mod:`.case`).
"""
from ..errors import set_unknown_field_hint
from ..geometry.sizing import MAX_ELEMENTS
from .canonical import canonical_json, canonical_number, content_id, is_number
from .case import MAX_NAME, ROUND3_DEFAULTS, ROUND4_DEFAULTS, CaseSpec
from .hints import case_field_hint
from .ground import LAYER_FIELDS, STRENGTH_DEFAULTS, Ground, Layer, Material, Strength
from .parts import (Boundaries, Design, Excavation, Geometry, Interface, Joints, Lining, Loads, MeshSettings,
                    Settlement, SolverSettings, Water)

__all__ = ["CaseSpec", "MAX_ELEMENTS", "canonical_json", "content_id", "canonical_number", "is_number",
           "ROUND3_DEFAULTS", "ROUND4_DEFAULTS", "MAX_NAME", "LAYER_FIELDS", "STRENGTH_DEFAULTS", "Ground", "Layer", "Material", "Strength",
           "Boundaries", "Design", "Excavation", "Geometry", "Interface", "Joints", "Lining", "Loads",
           "MeshSettings", "Settlement", "SolverSettings", "Water"]

set_unknown_field_hint(case_field_hint)

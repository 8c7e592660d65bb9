"""The "did you mean" of a mistyped field of a case (difflib over the fields of its section)."""
from __future__ import annotations

from ..errors import did_you_mean
from .case import CaseSpec
from .ground import Layer


def case_field_hint(path: str) -> str:
    """The "did you mean" of an unknown field at dotted ``path`` of a case (or of a sweep's ``base``):
    the closest field of the same section of :class:`solver.spec.CaseSpec`."""
    parts = path.split(".")
    if parts[0] == "base":  # a sweep's or study's base case
        parts = parts[1:]
    model = CaseSpec
    for part in parts[:-1]:
        if part.isdigit() and model is None:
            model = Layer
            continue
        info = getattr(model, "model_fields", {}).get(part)
        kind = getattr(info, "annotation", None)
        model = kind if isinstance(kind, type) and hasattr(kind, "model_fields") else None
        if part == "layers":
            model = None  # the next part is the layer's index
        elif model is None:
            return ""
    return did_you_mean(parts[-1], getattr(model, "model_fields", {})) if parts else ""

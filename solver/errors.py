"""One text for one mistake: pydantic validation errors as ``(dotted field, reason)``.

The API (422 bodies), the command line and sweep expansion all report invalid input
through :func:`field_errors`, so the same mistake reads the same everywhere, e.g.
``geometry.depth: cover above the tunnel is 0.2 m; ...``.

The case model's own checks (model validators) raise ``ValueError`` messages that start
with the path of the field they concern, relative to the model that raised them
(``"depth: cover ..."`` from ``geometry``, ``"lining.young: ..."`` from the case);
that path is joined to the location pydantic reports.
"""
from __future__ import annotations

import re
from typing import Any, Callable, Iterable, Sequence

__all__ = ["SolverError", "NotConvergedError", "GroundCollapseError", "NoAdmissibleBoltError", "field_errors",
           "field_path", "format_errors", "did_you_mean"]


class SolverError(RuntimeError):
    """A case that cannot be solved; never a result that only looks valid."""


_NAMED = re.compile(r"^([A-Za-z_]\w*(?:\.(?:[A-Za-z_]\w*|\d+))*): (.*)$", re.DOTALL)
#: Location prefixes FastAPI adds to pydantic's (where in the request the value was).
_REQUEST_PARTS = frozenset({"body", "query", "path", "header", "cookie"})


class NotConvergedError(SolverError):
    """The inner solver did not reach the tolerance within ``max_iterations``."""


class GroundCollapseError(NotConvergedError):
    """The unsupported ground cannot stand at the asked deconfinement: at its limit load the load it
    holds levels out or falls as it deforms (SPEC §9.1: a result, named with what the ground held).
    ``peak``: the released share of the excavation load at which it collapsed, where known."""

    def __init__(self, message: str, peak: float | None = None):
        super().__init__(message)
        self.peak = peak


class NoAdmissibleBoltError(SolverError):
    """No bolt node gave a non-negative bolt reaction (contradicts Theorem 3.3)."""


def field_path(loc: Sequence[Any], message: str, *, kind: str = "value_error") -> tuple[str, str]:
    """Dotted field path and reason of one pydantic error.

    >>> field_path(("geometry",), "Value error, depth: cover is 0.2 m")
    ('geometry.depth', 'cover is 0.2 m')
    >>> field_path(("solver", "bolt"), "Value error, bolt: theta 200 deg is outside [0, 180]")
    ('solver.bolt', 'theta 200 deg is outside [0, 180]')
    >>> field_path(("vary", "ground.young", 1), "Input should be a valid number", kind="float_type")
    ('vary.ground.young[1]', 'Input should be a valid number')
    >>> field_path(("ground",), "Value error, layers.1.thickness: must be > 0")
    ('ground.layers.1.thickness', 'must be > 0')
    """
    parts = list(loc)
    if parts and parts[0] in _REQUEST_PARTS:
        parts = parts[1:]
    reason = message.removeprefix("Value error, ")
    named = _NAMED.match(reason) if kind == "value_error" else None
    if named:  # our own validators name the field at the start of the message
        extra = named.group(1).split(".")
        if parts and parts[-1] == extra[0]:
            parts = parts[:-1]
        parts = [*parts, *(int(e) if e.isdigit() else e for e in extra)]
        reason = named.group(2)
    # an item of a case's list is a path step (``ground.layers.1.young``, as sweeps address it);
    # an item of a sweep's list of values is an index (``vary.ground.young[1]``)
    listed = bool(parts) and parts[0] == "vary"
    path = ""
    for p in parts:
        if isinstance(p, int) and listed:
            path += f"[{p}]"
        else:
            path += f".{p}" if path else str(p)
    return path, reason


def field_errors(errors: Iterable[dict] | Any) -> list[tuple[str, str]]:
    """``[(dotted field, reason)]`` of a ``pydantic.ValidationError`` (or its ``errors()`` list).

    A field path is empty when the error concerns the whole document.
    """
    if hasattr(errors, "errors"):
        errors = errors.errors()
    out = []
    for err in errors:
        if err.get("type") == "json_invalid":
            detail = str(err.get("ctx", {}).get("error", ""))
            out.append(("", f"invalid JSON: {detail}".rstrip(": ")))
            continue
        path, reason = field_path(err.get("loc", ()), str(err.get("msg", "")),
                                  kind=str(err.get("type", "value_error")))
        if err.get("type") == "extra_forbidden":
            reason = "unknown field" + _unknown_field_hint(path)
        out.append((path, reason))
    return out


def did_you_mean(word: str, choices: Iterable[str]) -> str:
    """``"; did you mean 'x'?"`` for the choice closest to a mistyped ``word`` (difflib), else ``""``."""
    from difflib import get_close_matches

    close = get_close_matches(word, list(choices), n=1, cutoff=0.6)
    return f"; did you mean {close[0]!r}?" if close else ""


#: How an unknown field is hinted at: the case model registers its "did you mean" here
#: (:func:`solver.spec.hints.case_field_hint`), so that this module, below every other, imports none.
_unknown_field_hint: Callable[[str], str] = lambda path: ""


def set_unknown_field_hint(hint: Callable[[str], str]) -> None:
    """Register ``hint(dotted path) -> text`` appended to "unknown field" (the case model does)."""
    global _unknown_field_hint
    _unknown_field_hint = hint


def format_errors(errors: Iterable[tuple[str, str]], *, whole: str = "value") -> str:
    """One line: ``field: reason; field: reason`` (``whole`` names an empty path)."""
    return "; ".join(f"{field or whole}: {reason}" for field, reason in errors)


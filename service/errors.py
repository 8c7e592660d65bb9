"""Error responses: every refusal says which field and why, in one JSON shape.

``{"detail": "...", "errors": [{"field": "geometry.depth", "reason": "...", "type": "..."}]}``

The case and sweep models report some problems from model-level validators whose
message starts with the dotted path (``"depth: cover above the tunnel ..."`` raised
by ``geometry``); :func:`field_path` joins that with the location pydantic gives.
"""
from __future__ import annotations

import re
from typing import Any, Iterable

from fastapi import Request
from fastapi.exceptions import RequestValidationError
from fastapi.responses import JSONResponse

from .schemas import ErrorBody, FieldError

_REQUEST_PARTS = ("body", "query", "path", "header", "cookie")
_MESSAGE_PATH = re.compile(r"^([A-Za-z_]\w*(?:\.[A-Za-z_]\w*)*): (.*)$", re.DOTALL)


def field_path(loc: Iterable[Any], message: str) -> tuple[str, str]:
    """Dotted field path and reason of one pydantic error.

    >>> field_path(("body", "geometry"), "Value error, depth: cover is 0.2 m")
    ('geometry.depth', 'cover is 0.2 m')
    >>> field_path(("body", "solver", "bolt"), "Value error, bolt: theta 200 deg is outside [0, 180]")
    ('solver.bolt', 'theta 200 deg is outside [0, 180]')
    """
    parts = [p for p in loc]
    if parts and parts[0] in _REQUEST_PARTS:
        parts = parts[1:]
    reason = message.removeprefix("Value error, ")
    named = _MESSAGE_PATH.match(reason)
    if named:
        extra = named.group(1).split(".")
        if parts and parts[-1] == extra[0]:
            parts = parts[:-1]
        parts = [*parts, *extra]
        reason = named.group(2)
    path = ""
    for p in parts:
        path += f"[{p}]" if isinstance(p, int) else (f".{p}" if path else str(p))
    return path or "body", reason


def field_errors(errors: Iterable[dict]) -> list[FieldError]:
    """pydantic/FastAPI error dicts as :class:`FieldError`."""
    out = []
    for err in errors:
        if err.get("type") == "json_invalid":
            ctx = err.get("ctx", {}).get("error", "")
            out.append(FieldError(field="body", reason=f"invalid JSON: {ctx}".rstrip(": "), type="json_invalid"))
            continue
        field, reason = field_path(err.get("loc", ()), str(err.get("msg", "")))
        out.append(FieldError(field=field, reason=reason, type=str(err.get("type", "value_error"))))
    return out


def invalid(errors: list[FieldError], status_code: int = 422) -> JSONResponse:
    """A 422 (or other) response listing ``errors``."""
    summary = "; ".join(f"{e.field}: {e.reason}" for e in errors)
    return JSONResponse(status_code=status_code,
                        content=ErrorBody(detail=f"invalid input: {summary}", errors=errors).model_dump())


async def request_validation_handler(request: Request, exc: RequestValidationError) -> JSONResponse:
    """422 naming each field; a malformed id or plot name in the path is simply unknown (404)."""
    errors = exc.errors()
    path_errors = [e for e in errors if e.get("loc", ("",))[0] == "path"]
    if path_errors:
        names = ", ".join(f"{e['loc'][-1]} {e.get('input')!r}" for e in path_errors)
        return JSONResponse(status_code=404, content=ErrorBody(detail=f"not found: unknown {names}").model_dump())
    return invalid(field_errors(errors))


#: Documented error responses, for the routes' ``responses=``.
def responses(*codes: int) -> dict[int, dict]:
    text = {401: "missing or wrong bearer token", 404: "unknown id", 409: "result not ready",
            413: "request body too large", 422: "invalid input (each field named)",
            503: "scheduler unreachable"}
    return {code: {"model": ErrorBody, "description": text[code]} for code in codes}

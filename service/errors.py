"""Error responses: every refusal says which field and why, in one JSON shape.

``{"detail": "...", "errors": [{"field": "geometry.depth", "reason": "...", "type": "..."}]}``

Field paths and reasons come from :func:`solver.errors.field_errors`, the one formatter
of validation errors that the command line and sweeps use too.
"""
from __future__ import annotations

import errno
import logging
from typing import Iterable

from fastapi import Request, Response
from fastapi.exception_handlers import http_exception_handler
from fastapi.exceptions import RequestValidationError
from fastapi.responses import JSONResponse
from starlette.exceptions import HTTPException as StarletteHTTPException

from solver.errors import field_errors as _field_reasons

from .job_tables import is_damage
from .schemas import ErrorBody, FieldError
from .views import error_page

logger = logging.getLogger(__name__)

#: OS errors that mean the results directory cannot take writes right now.
_WRITE_ERRNOS = frozenset({errno.ENOSPC, errno.EDQUOT, errno.EROFS, errno.EIO, errno.EACCES, errno.EPERM})


def field_errors(errors: Iterable[dict]) -> list[FieldError]:
    """pydantic/FastAPI error dicts as :class:`FieldError` (an empty path is the ``body``)."""
    errors = list(errors)
    return [FieldError(field=field or "body", reason=reason, type=str(err.get("type", "value_error")))
            for err, (field, reason) in zip(errors, _field_reasons(errors))]


#: Bounds of an error answer: a 1 MB body of bad values must not draw a 12 MB answer.
MAX_ERRORS = 50
MAX_REASON_CHARS = 300


def printable(text: str, limit: int = MAX_REASON_CHARS) -> str:
    """``text`` safe to send and short: lone surrogates (``"\\ud800"``, which UTF-8 cannot
    encode) escaped, cut at ``limit`` characters with how much was left out."""
    text = str(text).encode("utf-8", "backslashreplace").decode("utf-8")
    if len(text) > limit:
        text = f"{text[:limit]}… ({len(text) - limit:,} more characters)"
    return text


def invalid(errors: list[FieldError], status_code: int = 422) -> JSONResponse:
    """A 422 (or other) response listing ``errors`` (at most :data:`MAX_ERRORS`, each field
    and reason bounded and encodable)."""
    more = len(errors) - MAX_ERRORS
    errors = [FieldError(field=printable(e.field, 200), reason=printable(e.reason), type=printable(e.type, 60))
              for e in errors[:MAX_ERRORS]]
    if more > 0:
        errors.append(FieldError(field="body", reason=f"and {more:,} more errors not listed", type="too_many_errors"))
    summary = "; ".join(f"{e.field}: {e.reason}" for e in errors)
    return JSONResponse(status_code=status_code,
                        content=ErrorBody(detail=f"invalid input: {summary}", errors=errors).model_dump())


async def request_validation_handler(request: Request, exc: RequestValidationError) -> JSONResponse:
    """422 naming each field; a malformed id or plot name in the path is simply unknown (404)."""
    errors = exc.errors()
    path_errors = [e for e in errors if e.get("loc", ("",))[0] == "path"]
    if path_errors:
        names = ", ".join(f"{e['loc'][-1]} {e.get('input')!r}" for e in path_errors)
        detail = f"not found: unknown {names}"
        if _page_request(request):
            return await _error_page(request, 404, detail)
        return JSONResponse(status_code=404, content=ErrorBody(detail=detail).model_dump())
    return invalid(field_errors(errors))


async def store_error_handler(request: Request, exc: Exception) -> JSONResponse:
    """503 with the reason when the job records or the results directory refuse a write
    (full or read-only disk, I/O error), or when the job records are found damaged (their
    recovery is started: moved aside, rebuilt from the results); the reason names no server path."""
    if is_damage(exc):
        request.app.state.jobs.recover_soon(str(exc))
        reason = (f"job records are damaged ({exc}): they are being moved aside and rebuilt from the "
                  "stored results; retry in a few seconds")
        logger.error("%s (%s %s)", reason, request.method, request.url.path)
        return JSONResponse(status_code=503, content=ErrorBody(detail=reason).model_dump(),
                            headers={"Retry-After": "5"})
    if isinstance(exc, OSError):
        if exc.errno not in _WRITE_ERRNOS:
            raise exc  # not the store refusing writes: a server error
        reason = f"results store cannot take writes: {exc.strerror or type(exc).__name__}"
    else:
        reason = f"job records cannot take writes: {exc}"
    logger.error("%s (%s %s)", reason, request.method, request.url.path)
    return JSONResponse(status_code=503, content=ErrorBody(detail=reason).model_dump(),
                        headers={"Retry-After": "60"})


async def http_error_handler(request: Request, exc: StarletteHTTPException) -> Response:
    """FastAPI's answer to an HTTP error, except that a body it cannot parse at all (not
    UTF-8, say) is invalid input like any other: 422 naming the body, not 400."""
    if exc.status_code == 400:
        return invalid([FieldError(field="body", reason=f"cannot be parsed: {exc.detail}", type="json_invalid")])
    if exc.status_code >= 400 and _page_request(request):
        return await _error_page(request, exc.status_code, str(exc.detail))
    return await http_exception_handler(request, exc)


def _page_request(request: Request) -> bool:
    """Whether ``request`` asks for a dashboard page (``/ui/...``: answered in HTML, errors too)."""
    return request.url.path.startswith("/ui/")


async def _error_page(request: Request, status_code: int, detail: str) -> Response:
    """A page request's error as the dashboard's HTML error page: every page error (a
    malformed or unknown id, an unknown page) comes here, raised or refused by validation."""
    return await error_page(request, status_code, detail)


async def overflow_handler(request: Request, exc: OverflowError) -> JSONResponse:
    """422 for a number too large for the job records (e.g. a page offset of 1e23)."""
    return invalid([FieldError(field="query", reason=f"a number is out of range: {exc}", type="overflow")])


#: Documented error responses, for the routes' ``responses=``.
def responses(*codes: int) -> dict[int, dict]:
    text = {401: "missing or wrong bearer token", 404: "unknown id", 409: "result not ready",
            413: "request body too large", 422: "invalid input (each field named)",
            429: "too many open cases (header Retry-After)",
            503: "results store cannot take writes (the reason in detail)"}
    return {code: {"model": ErrorBody, "description": text[code]} for code in codes}

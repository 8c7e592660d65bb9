"""Request guards: the body size cap (before any parsing), the bearer token on POSTs, and
the capacity checks (free space, bounded queue) before work is accepted."""
from __future__ import annotations

import base64
import copy
import json
import secrets
import time
from typing import Optional

from fastapi import Depends, HTTPException, Request, status
from fastapi.security import HTTPAuthorizationCredentials, HTTPBearer

from workflows.files import can_write
from workflows.result_store import free_bytes

_bearer = HTTPBearer(auto_error=False, description="required on POST when TUNNEL_CONTACT_TOKEN is set")
#: How a client may prove it holds the token: as a bearer token, or as the password of HTTP
#: basic authentication (what a browser asks its user for; the user name is not checked).
CHALLENGE = 'Bearer, Basic realm="tunnel-contact", charset="UTF-8"'


def token_given(authorization: str, expected: str) -> bool:
    """Whether the ``Authorization`` header value carries ``expected`` (bearer or basic)."""
    scheme, _, value = authorization.partition(" ")
    scheme, value = scheme.lower(), value.strip()
    if scheme == "basic":
        try:
            value = base64.b64decode(value, validate=True).decode("utf-8").partition(":")[2]
        except (ValueError, UnicodeDecodeError):
            return False
    elif scheme != "bearer":
        return False
    return secrets.compare_digest(value.encode(), expected.encode())


async def require_token(request: Request,
                        credentials: Optional[HTTPAuthorizationCredentials] = Depends(_bearer)) -> None:
    """Refuse (401) a request without the configured token; no-op when none is configured."""
    expected = request.app.state.settings.token
    if not expected:
        return
    if not token_given(request.headers.get("authorization", ""), expected):
        raise HTTPException(status_code=status.HTTP_401_UNAUTHORIZED,
                            detail="missing or wrong bearer token",
                            headers={"WWW-Authenticate": CHALLENGE})


class TokenReadsMiddleware:
    """With ``settings.token_reads``, refuse (401) every request without the token but
    ``/health`` (an orchestrator's probe; it shows counts, no results). A page request gets
    the basic-authentication challenge, so a browser asks its user once and then sends the
    token with every request of the dashboard, its own ``fetch`` calls included."""

    OPEN_PATHS = ("/health",)

    def __init__(self, app, settings):
        self.app = app
        self.expected = settings.token if settings.token_reads else None

    async def __call__(self, scope, receive, send):
        if scope["type"] != "http" or self.expected is None or scope["path"] in self.OPEN_PATHS:
            await self.app(scope, receive, send)
            return
        headers = dict(scope["headers"])
        if token_given(headers.get(b"authorization", b"").decode("latin-1"), self.expected):
            await self.app(scope, receive, send)
            return
        payload = json.dumps({"detail": "this service needs its token to be read: send "
                                        "Authorization: Bearer <token> (or basic authentication with the "
                                        "token as the password)", "errors": []}).encode()
        await send({"type": "http.response.start", "status": 401,
                    "headers": [(b"content-type", b"application/json"),
                                (b"content-length", str(len(payload)).encode()),
                                # one challenge a line: browsers read the first scheme of a line
                                (b"www-authenticate", b'Basic realm="tunnel-contact", charset="UTF-8"'),
                                (b"www-authenticate", b"Bearer")]})
        await send({"type": "http.response.body", "body": payload})


def check_capacity(request: Request, new_cases: int = 1, need_bytes: int = 0) -> None:
    """Refuse work the service cannot take now.

    503 when the results store refuses writes (read-only, job records read-only) or has less
    free space than the new cases' results need (``need_bytes``, from their mesh estimates;
    at least ``settings.min_free_bytes``); 429 with ``Retry-After`` when ``new_cases`` more
    would put the queued and running cases over ``settings.max_open_cases``. The room the
    queued and running cases' results will take is held for them (:meth:`JobStore.open_room`):
    what they need is not offered again to new work.
    """
    if new_cases <= 0:
        return
    settings = request.app.state.settings
    jobs = request.app.state.jobs
    if not writable(request.app.state):
        raise HTTPException(status_code=status.HTTP_503_SERVICE_UNAVAILABLE,
                            detail="results store cannot take writes: the results directory or the job records "
                                   "are read-only; stored results are still served",
                            headers={"Retry-After": str(settings.retry_after)})
    need = max(settings.min_free_bytes, need_bytes)
    free = free_bytes(jobs.root)
    held = _held_room(request.app.state)  # the results of the cases accepted before
    if free - held < need:
        what = 'this case needs' if new_cases == 1 else f'these {new_cases:,} cases need'
        raise HTTPException(status_code=status.HTTP_503_SERVICE_UNAVAILABLE,
                            detail=f"results store is full: {free / 2**20:.1f} MiB free"
                                   + (f", {held / 2**20:.0f} MiB of it held for the queued and running cases"
                                      if held else "")
                                   + f"; {what} about {need / 2**20:.0f} MiB",
                            headers={"Retry-After": str(settings.retry_after)})
    open_cases = _open_cases(request.app.state, new_cases)
    if open_cases + new_cases > settings.max_open_cases:
        raise HTTPException(status_code=status.HTTP_429_TOO_MANY_REQUESTS,
                            detail=f"{open_cases:,} cases are queued or running, the limit is "
                                   f"{settings.max_open_cases:,}; retry later",
                            headers={"Retry-After": str(settings.retry_after)})
    _hold_room(request.app.state, need_bytes)


#: Seconds a writability check of the store is reused.
WRITABLE_TTL = 1.0


def writable(state) -> bool:
    """Results directory and job records take writes (checked at most every :data:`WRITABLE_TTL` s)."""
    now = time.monotonic()
    cached = getattr(state, "writable", None)
    if cached is None or now - cached[0] > WRITABLE_TTL:
        cached = (now, can_write(state.jobs.root) and state.jobs.store.writable())
        state.writable = cached
    return cached[1]


#: Seconds a count of open cases is reused (counting 10^4 queued records takes ~1 ms).
OPEN_COUNT_TTL = 0.25


def _open_cases(state, new_cases: int) -> int:
    """Queued + running cases, counted at most every :data:`OPEN_COUNT_TTL` s; cases accepted
    since the count are added, so the limit is overshot by none but concurrent sweeps."""
    now = time.monotonic()
    cached = getattr(state, "open_count", None)
    if cached is None or now - cached[0] > OPEN_COUNT_TTL:
        cached = (now, state.jobs.store.count_open())
    state.open_count = (cached[0], cached[1] + new_cases)  # this request's cases, until the next count
    return cached[1]


def _held_room(state) -> int:
    """Bytes held for the open cases' results, counted at most every :data:`OPEN_COUNT_TTL` s;
    the room of cases accepted since the count is added (as :func:`_open_cases` does)."""
    now = time.monotonic()
    cached = getattr(state, "held_room", None)
    if cached is None or now - cached[0] > OPEN_COUNT_TTL:
        cached = (now, state.jobs.store.open_room())
    state.held_room = cached
    return cached[1]


def _hold_room(state, need_bytes: int) -> None:
    """Count ``need_bytes`` as held until the next count (the request's cases were accepted)."""
    cached = getattr(state, "held_room", None)
    if cached is not None:
        state.held_room = (cached[0], cached[1] + need_bytes)


def openapi_auth_as_configured(app) -> None:
    """Declare the bearer token in the OpenAPI schema only when one is configured."""
    build = app.openapi

    def openapi() -> dict:
        schema = build()
        if app.state.settings.token:
            return schema
        schema = copy.deepcopy(schema)  # the built schema is cached: leave it whole
        schema.get("components", {}).pop("securitySchemes", None)
        for operations in schema.get("paths", {}).values():
            for operation in operations.values():
                if isinstance(operation, dict):
                    operation.pop("security", None)
                    operation.get("responses", {}).pop("401", None)
        return schema

    app.openapi = openapi


class BodyLimitMiddleware:
    """ASGI middleware answering 413 to a body over ``max_bytes``, before the app parses it.

    A declared ``Content-Length`` over the cap is refused at once; otherwise the body
    is read (never more than ``max_bytes`` + one chunk) and replayed to the app.
    """

    def __init__(self, app, max_bytes: int):
        self.app = app
        self.max_bytes = max_bytes

    async def __call__(self, scope, receive, send):
        if scope["type"] != "http" or scope["method"] in ("GET", "HEAD", "OPTIONS"):
            await self.app(scope, receive, send)
            return
        declared = dict(scope["headers"]).get(b"content-length")
        if declared is not None and declared.isdigit() and int(declared) > self.max_bytes:
            await self._refuse(send)
            return
        chunks, size = [], 0
        while True:
            message = await receive()
            if message["type"] == "http.disconnect":
                return
            chunks.append(message.get("body", b""))
            size += len(chunks[-1])
            if size > self.max_bytes:
                await self._refuse(send)
                return
            if not message.get("more_body", False):
                break
        body = b"".join(chunks)
        replayed = False

        async def replay():
            nonlocal replayed
            if not replayed:
                replayed = True
                return {"type": "http.request", "body": body, "more_body": False}
            return await receive()

        await self.app(scope, replay, send)

    async def _refuse(self, send) -> None:
        payload = json.dumps({"detail": f"request body over {self.max_bytes} bytes", "errors": []}).encode()
        await send({"type": "http.response.start", "status": 413,
                    "headers": [(b"content-type", b"application/json"),
                                (b"content-length", str(len(payload)).encode()),
                                (b"connection", b"close")]})
        await send({"type": "http.response.body", "body": payload})


#: Headers on every answer: no page of the service inside another site's frame (clickjacking),
#: no content sniffing, no URL leaked to other sites.
SECURITY_HEADERS = [(b"x-frame-options", b"DENY"), (b"content-security-policy", b"frame-ancestors 'none'"),
                    (b"x-content-type-options", b"nosniff"), (b"referrer-policy", b"same-origin")]


class SameOriginMiddleware:
    """ASGI middleware refusing state-changing requests sent from another site, with or
    without a token (a form or script on another origin can make a browser POST, and with
    no token configured nothing else would stop it), and adding :data:`SECURITY_HEADERS`.

    A ``POST`` (any method but GET/HEAD/OPTIONS) is refused with 403 when its ``Origin``
    is present and is not this service's own origin (scheme and ``Host``), or when the
    browser marks it ``Sec-Fetch-Site: cross-site``. Requests without either header (curl,
    httpx, the CLI, other servers) are not browsers acting for someone else and pass; the
    dashboard's own ``fetch`` calls are same-origin. This is the CSRF defence of the
    dashboard's forms, which post JSON through ``fetch`` only.
    """

    def __init__(self, app):
        self.app = app

    async def __call__(self, scope, receive, send):
        if scope["type"] != "http":
            await self.app(scope, receive, send)
            return
        if scope["method"] not in ("GET", "HEAD", "OPTIONS"):
            reason = self._cross_site(scope)
            if reason:
                await self._refuse(send, reason)
                return

        async def with_headers(message):
            if message["type"] == "http.response.start":
                names = {k.lower() for k, _ in message.get("headers", [])}
                message["headers"] = list(message.get("headers", [])) + [
                    (k, v) for k, v in SECURITY_HEADERS if k not in names]
            await send(message)

        await self.app(scope, receive, with_headers)

    @staticmethod
    def _cross_site(scope) -> Optional[str]:
        headers = {k.lower(): v for k, v in scope["headers"]}
        origin = headers.get(b"origin")
        host = headers.get(b"host", b"").decode("latin-1").lower()
        if origin is not None:
            text = origin.decode("latin-1").lower()
            own = {f"{scheme}://{host}" for scheme in ("http", "https")}
            if text == "null" or text not in own:
                return f"cross-site request refused: Origin {text!r} is not this service ({host!r})"
        if headers.get(b"sec-fetch-site", b"").lower() == b"cross-site":
            return "cross-site request refused (Sec-Fetch-Site: cross-site)"
        return None

    @staticmethod
    async def _refuse(send, reason: str) -> None:
        payload = json.dumps({"detail": reason, "errors": []}).encode()
        await send({"type": "http.response.start", "status": 403,
                    "headers": [(b"content-type", b"application/json"),
                                (b"content-length", str(len(payload)).encode()), *SECURITY_HEADERS]})
        await send({"type": "http.response.body", "body": payload})


def host_allowed(host: str, allowed: tuple[str, ...]) -> bool:
    """Whether the ``Host`` header value ``host`` (a name or address, perhaps with a port)
    names one of ``allowed`` (exact names, ``*.domain`` for a domain's names, ``*`` for any)."""
    host = host.strip().lower()
    if host.startswith("["):  # [::1]:8000
        name = host[1:].partition("]")[0]
    else:
        name = host.rpartition(":")[0] if host.count(":") == 1 else host
    name = name.rstrip(".")
    return any(pattern == "*" or name == pattern
               or (pattern.startswith("*.") and name.endswith(pattern[1:])) for pattern in allowed)


class AllowedHostsMiddleware:
    """ASGI middleware answering 400 to a request whose ``Host`` header is not one of
    ``settings.allowed_hosts`` (or the address the service is bound to, ``settings.host``): what DNS rebinding sends (a page of another site whose name
    now points at this machine carries that site's name), with or without a token. A request
    without a ``Host`` header (HTTP/1.0) is no browser's and passes."""

    def __init__(self, app, settings):
        self.app = app
        bound = settings.host.strip("[]").lower()
        # the address it is bound to, when one (clients reach it by that address; rebinding uses names)
        self.allowed = settings.allowed_hosts + (() if bound in ("", "0.0.0.0", "::") else (bound,))

    async def __call__(self, scope, receive, send):
        if scope["type"] != "http" or "*" in self.allowed:  # (the service has no websockets)
            await self.app(scope, receive, send)
            return
        host = dict(scope["headers"]).get(b"host")
        if host is None or host_allowed(host.decode("latin-1"), self.allowed):
            await self.app(scope, receive, send)
            return
        shown = host.decode("latin-1")[:100]
        payload = json.dumps({"detail": f"host {shown!r} is not one this service answers to (allowed: "
                                        f"{', '.join(self.allowed)}; set TUNNEL_CONTACT_ALLOWED_HOSTS)",
                              "errors": []}).encode()
        await send({"type": "http.response.start", "status": 400,
                    "headers": [(b"content-type", b"application/json"),
                                (b"content-length", str(len(payload)).encode()), *SECURITY_HEADERS]})
        await send({"type": "http.response.body", "body": payload})

"""The dashboard's rendering: its Jinja templates and static files, the page frame every page
shares (the link to dask's own dashboard), and the HTML error page.

:mod:`service.pages` (the pages) and :mod:`service.errors` (a page request's error answered in
HTML) both render through here, so the errors need not import the pages.
"""
from __future__ import annotations

import json
import logging
import time
from pathlib import Path
from typing import Optional

import httpx
from fastapi import FastAPI, Request
from fastapi.responses import HTMLResponse
from fastapi.staticfiles import StaticFiles
from fastapi.templating import Jinja2Templates

from .comparison import shown
from .params import jobs_of

logger = logging.getLogger(__name__)

HERE = Path(__file__).parent
templates = Jinja2Templates(directory=HERE / "templates")
templates.env.filters["shown"] = shown
templates.env.filters["pretty_json"] = lambda value: json.dumps(value, indent=2, sort_keys=True)


def mount_static(app: FastAPI) -> None:
    """Serve the dashboard's script and style sheet under ``/static``."""
    app.mount("/static", StaticFiles(directory=HERE / "static"), name="static")


async def dask_dashboard(request: Request) -> Optional[str]:
    """Link to the dask scheduler's dashboard, when the scheduler serves one.

    A scheduler always lists its HTTP server as ``dashboard``, even without bokeh or
    with ``--no-dashboard``; so the link is shown only if it answers (checked once a
    minute).
    """
    jobs = jobs_of(request)
    if not jobs.connected:
        return None
    try:
        if "dashboard" not in jobs.client.scheduler_info().get("services", {}):
            return None
        link = jobs.client.dashboard_link
    except Exception as exc:  # an older or unusual scheduler: no link rather than no page
        logger.debug("no dask dashboard link: %s", exc)
        return None
    checked = _dashboard_checks.get(link)
    if checked is None or time.monotonic() - checked[0] > _DASHBOARD_CHECK_EVERY:
        try:
            async with httpx.AsyncClient(timeout=1.0) as http:
                serves = (await http.get(link)).status_code == 200
        except httpx.HTTPError:
            serves = False
        checked = _dashboard_checks[link] = (time.monotonic(), serves)
    return link if checked[1] else None


_DASHBOARD_CHECK_EVERY = 60.0
_dashboard_checks: dict[str, tuple[float, bool]] = {}


async def render(request: Request, name: str, **context) -> HTMLResponse:
    return templates.TemplateResponse(request, name, {"dask_dashboard": await dask_dashboard(request), **context})


async def error_page(request: Request, status_code: int, detail: str) -> HTMLResponse:
    """The HTML error page (what :mod:`service.errors` answers a page request's HTTP error with)."""
    response = await render(request, "error.html", status_code=status_code, detail=detail)
    response.status_code = status_code
    return response

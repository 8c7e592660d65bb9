"""The FastAPI application: ``create_app(settings)``.

The dask client, the job records and the dispatcher are created in the ``lifespan``
hook and kept on ``app.state``; routes only validate, record, submit and answer.
"""
from __future__ import annotations

import gc
import logging
from contextlib import asynccontextmanager
from typing import Optional

from fastapi import FastAPI
from fastapi.exceptions import RequestValidationError
from starlette.exceptions import HTTPException as StarletteHTTPException

from workflows.files import DamagedFile
from workflows.result_store import ResultStore

from . import case_tables, cases, health, pages, reliability, searches, studies, sweeps
from .cluster import cluster_connection
from .errors import (damaged_file_handler, http_error_handler, overflow_handler, request_validation_handler,
                     store_error_handler)
from .guards import (AllowedHostsMiddleware, BodyLimitMiddleware, SameOriginMiddleware, TokenReadsMiddleware,
                     openapi_auth_as_configured)
from .jobs import Dispatcher
from .searches import Searches
from .settings import Settings, get_settings
from .job_stores import open_records
from .job_tables import DATABASE_ERRORS
from .views import mount_static

logger = logging.getLogger(__name__)


@asynccontextmanager
async def lifespan(app: FastAPI):
    """Open the job records, connect to dask, recover unfinished cases; undo on shutdown."""
    settings: Settings = app.state.settings
    root = results_root(settings)
    store, damage = open_records(settings, background_checkpoints=True)
    try:
        async with cluster_connection(settings) as connect:
            jobs = Dispatcher(connect, store, root, poll_interval=settings.poll_interval,
                              reconcile_interval=settings.reconcile_interval)
            if damage is not None:
                await jobs.rebuild_records()
            await jobs.start()
            app.state.jobs = jobs
            app.state.searches = Searches(jobs)
            app.state.searches.resume()  # searches left running by an earlier run go on
            reliability.resume(app)  # and reliability studies
            # Everything imported and built so far lives as long as the process. Taking it
            # out of the collector's view keeps full collections (~0.1 s over the ~200k
            # objects of dask, xarray, pydantic) from stalling requests.
            gc.collect()
            gc.freeze()
            logger.info("tunnel-contact service ready; results in %s", root)
            try:
                yield
            finally:
                await app.state.reliability.stop()
                await app.state.searches.stop()
                await jobs.stop()
    finally:
        store.close()


def results_root(settings: Settings):
    """The results as the dispatcher hands them on: the resolved folder, or, for object storage,
    the store itself (its URL goes to the workers, its cache folder serves files here); the
    folder (cache) is made, and the bucket if missing."""
    store = ResultStore(settings.results)
    store.root.mkdir(parents=True, exist_ok=True)
    if store.url is None:
        return store.root.resolve()
    store.remote.make_bucket()
    return store


def create_app(settings: Optional[Settings] = None) -> FastAPI:
    """The service as an ASGI app (``uvicorn --factory service.app:create_app`` works too).

    Parameters
    ----------
    settings : defaults to :func:`service.settings.get_settings` (the environment).
    """
    from importlib.metadata import PackageNotFoundError, version

    try:
        app_version = version("tunnel-contact")
    except PackageNotFoundError:
        app_version = "0"
    app = FastAPI(title="tunnel-contact", version=app_version, lifespan=lifespan, docs_url=None, redoc_url=None,
                  description="Tunnel lining / ground unilateral contact: submit cases and sweeps, "
                              "fetch results (netCDF) and plots. Work runs on a dask cluster.")
    app.state.settings = settings or get_settings()
    app.add_middleware(BodyLimitMiddleware, max_bytes=app.state.settings.max_body_bytes)
    app.add_middleware(TokenReadsMiddleware, settings=app.state.settings)
    app.add_middleware(SameOriginMiddleware)  # a cross-site POST is refused before its body is read
    app.add_middleware(AllowedHostsMiddleware, settings=app.state.settings)  # outermost: a foreign Host, first
    app.add_exception_handler(RequestValidationError, request_validation_handler)
    for error in (*DATABASE_ERRORS, OSError):  # full, read-only, locked, damaged, away: 503
        app.add_exception_handler(error, store_error_handler)
    app.add_exception_handler(OverflowError, overflow_handler)
    app.add_exception_handler(DamagedFile, damaged_file_handler)
    app.add_exception_handler(StarletteHTTPException, http_error_handler)
    openapi_auth_as_configured(app)
    for module in (cases, case_tables, sweeps, studies, searches, reliability, health, pages):
        app.include_router(module.router)
    mount_static(app)
    serve_docs_offline(app)
    return app


def serve_docs_offline(app: FastAPI) -> None:
    """``/docs`` (Swagger UI) and ``/redoc`` from assets shipped with the service (the
    ``fastapi-offline`` wheel's copies of swagger-ui and redoc): the pages work without any
    outside network, as SPEC §6 asks, where FastAPI's defaults load them from a CDN."""
    from pathlib import Path

    import fastapi_offline
    from fastapi.openapi.docs import get_redoc_html, get_swagger_ui_html
    from fastapi.staticfiles import StaticFiles

    assets = Path(fastapi_offline.__file__).parent / "static"
    app.mount("/docs-assets", StaticFiles(directory=assets), name="docs-assets")

    @app.get("/docs", include_in_schema=False)
    async def swagger_ui():
        return get_swagger_ui_html(openapi_url=app.openapi_url, title=f"{app.title} - API",
                                   swagger_js_url="/docs-assets/swagger-ui-bundle.js",
                                   swagger_css_url="/docs-assets/swagger-ui.css",
                                   swagger_favicon_url="/docs-assets/favicon.png")

    @app.get("/redoc", include_in_schema=False)
    async def redoc():
        return get_redoc_html(openapi_url=app.openapi_url, title=f"{app.title} - API",
                              redoc_js_url="/docs-assets/redoc.standalone.js",
                              redoc_favicon_url="/docs-assets/favicon.png", with_google_fonts=False)

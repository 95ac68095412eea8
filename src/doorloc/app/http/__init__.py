"""The HTTP service: ``create_app(settings)`` builds one FastAPI app with its own state and metrics.

Routes: ``POST /v1/locate``, ``GET /v1/doors``, ``GET|PUT /v1/doors/{door_id}``, ``GET /v1/cell``,
``GET /healthz``, ``GET /readyz``, ``GET /metrics``, ``GET /`` (operator page); OpenAPI at ``/openapi.json``.
Errors are ``application/problem+json`` (:mod:`doorloc.app.http.problems`).

Examples
--------
>>> from fastapi.testclient import TestClient
>>> from doorloc.app.settings import ServiceSettings
>>> app = create_app(ServiceSettings(cell=None, allowed_hosts=["testserver"]))
>>> with TestClient(app) as client:
...     client.get("/healthz").json(), client.get("/readyz").status_code
({'status': 'ok'}, 503)
"""

from __future__ import annotations

from contextlib import asynccontextmanager
from pathlib import Path
from typing import Any

import anyio
import anyio.to_thread
from fastapi import FastAPI
from fastapi.staticfiles import StaticFiles

from doorloc import __version__
from doorloc.app.answer import LocateFn
from doorloc.app.http import routes_doors, routes_locate, routes_ops
from doorloc.app.http.guards import BodyDeadline, HostCheck, KeyGate, LocateShedding, SecurityHeaders
from doorloc.app.http.metrics import ServiceMetrics
from doorloc.app.http.middleware import BodySizeLimit, LocateAdmission, RequestContext
from doorloc.app.http.problems import install_problem_handlers
from doorloc.app.http.state import ServiceState
from doorloc.app.settings import ServiceSettings
from doorloc.cell import Cell

__all__ = ["create_app", "create_app_from_env"]

STATIC_DIR = Path(__file__).resolve().parents[1] / "static"


def create_app(
    settings: ServiceSettings,
    *,
    cell: Cell | None = None,
    store: Any | None = None,
    locate_fn: LocateFn | None = None,
) -> FastAPI:
    """Build the service.

    Parameters
    ----------
    settings : ServiceSettings
        Limits, paths and keys (see :mod:`doorloc.app.settings`).
    cell, store, locate_fn : optional
        Given ones are used as they are; missing ones are loaded at start-up (cell from ``settings.cell``,
        recipe store from ``settings.database_url``, locate = :func:`doorloc.vision.locate.locate`).
    """
    state = ServiceState(
        settings=settings, metrics=ServiceMetrics(), cell=cell, store=store, locate_fn=locate_fn
    )

    @asynccontextmanager
    async def lifespan(app: FastAPI):
        import cv2

        # Requests already run in parallel threads; OpenCV's own pool on top would oversubscribe the cores.
        cv2.setNumThreads(settings.opencv_threads)
        # (while the worker processes locate, locate_fn stays None: load then starts them, once)
        if not state.ready or state.locate_fn is None or state.keys is None:
            await anyio.to_thread.run_sync(state.load)
        try:
            async with anyio.create_task_group() as tg:
                tg.start_soon(_sample_process_forever, state.metrics)
                yield
                tg.cancel_scope.cancel()
        finally:
            for pool in (state.workers, state.decoders, state.over_share):
                if pool is not None:
                    pool.close()

    app = FastAPI(
        title="doorloc",
        version=__version__,
        summary="Locate a wooden door in a milling cell and turn its recipe into robot targets.",
        lifespan=lifespan,
        # /docs is the bundled Swagger UI (routes_ops.api_docs), not FastAPI's page that loads it from a CDN
        docs_url=None,
        redoc_url=None,
    )
    app.state.service = state
    install_problem_handlers(app)
    app.include_router(routes_ops.router)
    app.include_router(routes_locate.router, tags=["locate"])
    app.include_router(routes_doors.router)
    app.mount("/static", StaticFiles(directory=STATIC_DIR), name="static")
    # add_middleware wraps from the inside out: RequestContext sees every request, including 413s; the host
    # and the key are checked before a byte of the body is read (KeyGate outside the body readers)
    app.add_middleware(LocateAdmission, deadline_s=settings.request_deadline_s)
    app.add_middleware(BodyDeadline, timeout_s=settings.body_timeout_s)
    app.add_middleware(BodySizeLimit, max_body_bytes=settings.max_upload_bytes)
    app.add_middleware(LocateShedding, state=state)
    app.add_middleware(KeyGate, state=state, routes=app.router.routes)
    app.add_middleware(HostCheck, allowed=settings.allowed_hosts, open_access=settings.open_access)
    app.add_middleware(SecurityHeaders)
    app.add_middleware(RequestContext, metrics=state.metrics)
    return app


async def _sample_process_forever(metrics: ServiceMetrics, every_s: float = 5.0) -> None:
    """Keep this worker's process figures fresh, so a scrape answered by another worker sees them too."""
    while True:  # cancelled at shutdown
        metrics.sample_process()
        await anyio.sleep(every_s)


def create_app_from_env() -> FastAPI:
    """App factory for ``uvicorn --factory`` (``doorloc serve``): JSON logs, settings from DOORLOC_*."""
    from doorloc.app.logs import configure_json_logging

    settings = ServiceSettings()
    configure_json_logging(settings.log_level)
    return create_app(settings)

"""The application factory: :func:`create_app` builds one service from its settings."""

from __future__ import annotations

import asyncio
import contextlib
import logging
from collections.abc import AsyncIterator
from contextlib import asynccontextmanager
from pathlib import Path
from typing import Any

from fastapi import FastAPI, HTTPException, Request
from fastapi.concurrency import run_in_threadpool
from fastapi.exceptions import RequestValidationError
from fastapi.responses import JSONResponse
from starlette.exceptions import HTTPException as StarletteHTTPException

from hrtls import __version__
from hrtls.service import schemas
from hrtls.service.clock import Clock, wall_clock
from hrtls.service.db import make_engine, migrate, session_factory, transaction
from hrtls.service.deps import Services
from hrtls.service.events import EventLog
from hrtls.service.headers import SecurityHeaders, content_security_policy
from hrtls.service.host import HostParams, TrackerHost
from hrtls.service.hub import Hub
from hrtls.service.limits import BodyLimit, RateLimiter
from hrtls.service.mission_runner import MissionRunner, MissionRunnerParams
from hrtls.service.runner import TrackerRunner, make_runner
from hrtls.service.security import has_commander, issue
from hrtls.service.settings import Settings
from hrtls.service.tokencache import TokenCache

API_PREFIX = schemas.API_PREFIX
log = logging.getLogger(__name__)


def bootstrap(settings: Settings, *, clock: Clock = wall_clock,
              new_commander: bool = False) -> str | None:
    """Migrate the database; create a commander token when there is none (or when asked).

    Returns the new token's secret (to print once) or None.
    """
    engine = make_engine(settings.db_url)
    try:
        migrate(engine)
        with transaction(session_factory(engine)) as db:
            if has_commander(db) and not new_commander:
                return None
            label = "first commander" if not has_commander(db) else "commander"
            _, secret = issue(db, role="commander", label=label, now_unix=clock())
            return secret
    finally:
        engine.dispose()


def _error_text(exc: RequestValidationError) -> tuple[str, list[dict[str, Any]]]:
    errors = [{"loc": list(e.get("loc", ())), "msg": str(e.get("msg", ""))}
              for e in exc.errors()]
    text = "; ".join(f"{'.'.join(str(p) for p in e['loc'])}: {e['msg']}" for e in errors)
    return text or "invalid request", errors


async def _publish_loop(services: Services) -> None:
    """Every ``1 / publish_hz`` s: push the changes of each mission to its sockets."""
    period = 1.0 / services.settings.publish_hz
    while True:
        await asyncio.sleep(period)
        try:
            deltas = await run_in_threadpool(services.publish_once)
        except Exception:
            log.exception("publishing failed")
            continue
        for mission_id, delta in deltas:
            services.hub.publish(mission_id, delta)


def create_app(settings: Settings, *, clock: Clock = wall_clock,
               runner: TrackerRunner | None = None) -> FastAPI:
    """The FastAPI application of one deployment (database migrated on start-up)."""
    services = _services(settings, clock=clock, runner=runner)

    @asynccontextmanager
    async def lifespan(app: FastAPI) -> AsyncIterator[None]:
        await run_in_threadpool(services.host.start)
        services.missions.start()
        publisher = asyncio.create_task(_publish_loop(services))
        try:
            yield
        finally:
            publisher.cancel()
            with contextlib.suppress(asyncio.CancelledError):
                await publisher
            await run_in_threadpool(services.missions.stop)
            await run_in_threadpool(services.host.stop)
            services.engine.dispose()

    app = FastAPI(title="hrtls supervisor", version=__version__, lifespan=lifespan,
                  docs_url=f"{API_PREFIX}/docs", openapi_url=f"{API_PREFIX}/openapi.json",
                  redoc_url=None)
    app.state.services = services
    _add_error_handlers(app)
    _add_routes(app, settings)
    _mount_dashboard(app, settings.web_root)
    app.add_middleware(BodyLimit, max_bytes=settings.max_body_bytes)
    app.add_middleware(SecurityHeaders, csp=content_security_policy(settings.basemap_url),
                       docs_prefix=f"{API_PREFIX}/docs")
    if settings.cors_origins:
        from fastapi.middleware.cors import CORSMiddleware

        app.add_middleware(CORSMiddleware, allow_origins=list(settings.cors_origins),
                           allow_credentials=True, allow_methods=["*"],
                           allow_headers=["Authorization", "Content-Type"])
    return app


def _services(settings: Settings, *, clock: Clock, runner: TrackerRunner | None) -> Services:
    """Database (migrated), event log, tracker host, socket hub and limits of a deployment."""
    engine = make_engine(settings.db_url)
    migrate(engine)
    sessions = session_factory(engine)
    hub = Hub()
    events = EventLog(sessions, hub, clock)
    host = TrackerHost(sessions=sessions, clock=clock, runner=runner or make_runner(settings),
                       params=HostParams(queue_batches=settings.queue_batches,
                                         snapshot_every_s=settings.snapshot_every_s,
                                         workers=settings.tracker_threads),
                       events=events)
    return Services(settings=settings, engine=engine, sessions=sessions, clock=clock,
                    agent_rate=RateLimiter(rate_hz=settings.rate_per_agent_hz,
                                           burst=settings.rate_burst, clock=clock),
                    host=host, hub=hub, events=events,
                    missions=MissionRunner(sessions=sessions, clock=clock, hub=hub,
                                           params=MissionRunnerParams(
                                               snapshot_every_s=settings.snapshot_every_s)),
                    tokens=TokenCache(ttl_s=settings.token_cache_ttl_s,
                                      max_entries=settings.token_cache_entries))


def _add_error_handlers(app: FastAPI) -> None:
    """Validation errors as one readable ``detail`` (plus the list); HTTP errors as JSON."""

    @app.exception_handler(RequestValidationError)
    async def _invalid(request: Request, exc: RequestValidationError) -> JSONResponse:
        text, errors = _error_text(exc)
        return JSONResponse({"detail": text, "errors": errors}, status_code=422)

    @app.exception_handler(StarletteHTTPException)
    async def _http(request: Request, exc: StarletteHTTPException) -> JSONResponse:
        return JSONResponse({"detail": str(exc.detail)}, status_code=exc.status_code,
                            headers=getattr(exc, "headers", None))


def _add_routes(app: FastAPI, settings: Settings) -> None:
    """The API routers under ``API_PREFIX``, the health check and a 404 for anything else."""
    from hrtls.service.routes import (
        agents,
        auth,
        dashboard,
        ingest,
        live,
        missions,
        network,
        orders,
        positions,
    )
    from hrtls.service.routes import events as event_routes

    for router in (auth.router, missions.router, agents.router, ingest.router, positions.router,
                   live.router, event_routes.router, orders.router, dashboard.router,
                   network.router):
        app.include_router(router, prefix=API_PREFIX)

    @app.get(f"{API_PREFIX}/health", response_model=schemas.HealthOut, tags=["health"])
    def health() -> schemas.HealthOut:
        return schemas.HealthOut(status="ok", version=__version__, db=settings.backend)

    @app.api_route(f"{API_PREFIX}/{{rest:path}}", methods=["GET", "POST", "PUT", "PATCH",
                                                           "DELETE"], include_in_schema=False)
    def _unknown(rest: str) -> None:
        raise HTTPException(404, f"no route {API_PREFIX}/{rest}")


def _mount_dashboard(app: FastAPI, web_root: Path | None) -> None:
    """Serve the dashboard's static files at ``/`` when they are installed."""
    if web_root is None:
        try:
            from hrtls.web import asset_root
        except ImportError:
            return
        web_root = asset_root()
    if not (web_root / "index.html").is_file():
        return
    from fastapi.staticfiles import StaticFiles

    app.mount("/", StaticFiles(directory=web_root, html=True), name="dashboard")

"""The FastAPI application. `create_app()` builds it; the engine is made in the lifespan."""

from __future__ import annotations

import asyncio
import logging
import sys
from contextlib import asynccontextmanager
from pathlib import Path

from fastapi import FastAPI, HTTPException, Request, Response, status
from fastapi.responses import FileResponse, JSONResponse
from fastapi.staticfiles import StaticFiles
from prometheus_client import CONTENT_TYPE_LATEST, generate_latest
from sqlalchemy.exc import DataError
from starlette.concurrency import run_in_threadpool

from backend import health
from backend.accounts.gate import HashingGate
from backend.accounts.throttle import LoginThrottle, Policy
from backend.alarms import distribution as alarm_distribution
from backend.alarms import queries as alarm_queries
from backend.alarms.monitor import AlarmMonitor
from backend.api import (
    alarm_review,
    alarms,
    audit,
    auth,
    browser_ws,
    jobs,
    labelling,
    misc,
    registry,
    robot_ws,
    robots,
    storage,
    users,
    videos,
)
from backend.body_limit import BodySizeLimit
from backend.db import make_engine, make_session_factory
from backend.deps import SESSION_COOKIE, CurrentUser
from backend.distribution import routing as distribution_routing
from backend.distribution.listener import StatusListener
from backend.distribution.sender import AlertSender
from backend.gc_tuning import collector_tuned_for_ingest
from backend.http_guards import SecurityMiddleware
from backend.ingest.stall_actions import StallActions, journal_path
from backend.ingest.waiting import SharedWaiting
from backend.ingest.writer import FrameWriter
from backend.leadership import Leadership, lock_for
from backend.metrics import Metrics
from backend.models.alarms import AlarmKind
from backend.realtime.bus import AlarmBus
from backend.realtime.hub import BrowserHub
from backend.realtime.robot_registry import RobotRegistry
from backend.registry.push import AssignmentPusher
from backend.services import Distribution, Duties, Fanout, Labelling, Services, ServicesDep
from backend.settings import Settings
from backend.storage.service import SummaryCache
from backend.unit_of_work import in_event_loop
from vigil.states import IllegalTransition

log = logging.getLogger("vigil.backend")

ROUTERS = (
    auth.router,
    misc.router,
    users.router,
    robots.router,
    alarms.router,
    alarm_review.router,
    audit.router,
    videos.router,
    registry.router,
    jobs.router,
    storage.router,
)


def create_app(settings: Settings | None = None) -> FastAPI:
    settings = settings or Settings()

    @asynccontextmanager
    async def lifespan(app: FastAPI):
        # The ingest writer thread waits on the database many times per flush; each time it
        # must win the GIL back from the event loop. A shorter switch interval (default 5 ms)
        # keeps those hand-overs from dominating commit latency.
        sys.setswitchinterval(settings.gil_switch_interval_s)
        services = await start_services(settings)
        app.state.services = services
        reconcile = asyncio.create_task(services.assignments.reconcile_forever())
        try:
            with collector_tuned_for_ingest():
                yield
        finally:
            reconcile.cancel()
            await stop_services(services)

    app = FastAPI(
        title="Vigil",
        version="0.1.0",
        description="Emergency detection for autonomous hospital patient transports.",
        lifespan=lifespan,
    )
    app.add_middleware(BodySizeLimit, settings=settings)
    app.add_middleware(
        SecurityMiddleware, cookie_name=SESSION_COOKIE, trusted_origins=settings.trusted_origins
    )
    for router in ROUTERS:
        app.include_router(router)
    labelling.install(app)
    app.include_router(robot_ws.router)
    app.include_router(browser_ws.router)

    @app.get("/metrics", tags=["system"], response_class=Response)
    def prometheus_metrics(user: CurrentUser, services: ServicesDep) -> Response:
        metrics = services.metrics
        with services.session_factory() as session:
            counts = alarm_queries.unresolved_counts(session)
        for kind in AlarmKind:
            metrics.open_alarms.labels(kind.value).set(counts.get(kind, 0))
        storage = services.storage_summary.latest(services.session_factory, settings)
        if storage is not None:
            metrics.set_storage(storage)
        return Response(generate_latest(metrics.registry), media_type=CONTENT_TYPE_LATEST)

    @app.exception_handler(IllegalTransition)
    def illegal_transition(request: Request, error: IllegalTransition) -> JSONResponse:
        # Every state machine (vigil.states): a transition its state does not allow.
        return JSONResponse({"detail": str(error)}, status_code=409)

    @app.exception_handler(DataError)
    def unstorable_value(request: Request, error: DataError) -> JSONResponse:
        # e.g. a NUL byte in a text field on PostgreSQL: the client's value, not our fault.
        reason = str(error.orig).splitlines()[0] if error.orig else "invalid value"
        return JSONResponse({"detail": f"value cannot be stored: {reason}"}, status_code=422)

    @app.exception_handler(OverflowError)
    def integer_out_of_range(request: Request, error: OverflowError) -> JSONResponse:
        # SQLite raises this for integers beyond 64 bits, e.g. an absurd id in a path.
        return JSONResponse({"detail": f"value out of range: {error}"}, status_code=422)

    _mount_frontend(app, settings.frontend_dir)
    return app


async def start_services(settings: Settings) -> Services:
    """Build every service of the process (in the lifespan: some are bound to its event loop)."""
    engine = make_engine(
        settings.database_url,
        pool_size=settings.database_pool_size,
        max_overflow=settings.database_max_overflow,
    )
    factory = make_session_factory(engine)
    log.info("database %s", engine.url.render_as_string(hide_password=True))
    database = await health.check_database(engine, settings.health_timeout_s)
    if database != "ok":  # serve anyway (liveness), but say so: readiness answers 503
        log.error(
            "database %s: not ready (%s)", engine.url.render_as_string(hide_password=True), database
        )
    metrics = Metrics()
    hub = BrowserHub()
    bus = AlarmBus(hub, settings.redis_url, settings.redis_channel)
    await bus.start()
    robots = RobotRegistry(on_change=metrics.connected_robots.set)
    assignments = AssignmentPusher(factory, robots, settings.assignment_resend_s)
    effects = Fanout(bus, assignments, robots)
    writer = FrameWriter(
        factory,
        metrics,
        effects,
        flush_ms=settings.ingest_flush_ms,
        flush_frames=settings.ingest_flush_frames,
        max_flush_frames=settings.ingest_max_flush_frames,
        unstored_alarm_ms=settings.unstored_alarm_ms,
        storage_stall_s=settings.storage_stall_seconds,
        stall_actions=StallActions(
            journal_path(settings.database_url, settings.stall_actions_path)
        ),
    )
    writer.start()
    waiting = SharedWaiting(
        writer.waiting_robots, bus.redis, f"{settings.redis_channel}.waiting.", bus.origin
    )
    waiting.start()
    monitor = AlarmMonitor(
        factory,
        settings,
        effects,
        waiting_robots=writer.waiting_robots,
        waiting_elsewhere=waiting.elsewhere,
        viewers=hub.viewers,
    )
    distribution = build_distribution(settings, factory, effects)
    if distribution is not None:
        bus.on_remote.append(lambda alarm: distribution.sender.wake())
    duties = Duties(monitor, distribution)
    leadership = Leadership(
        lock_for(settings.database_url),
        on_lead=duties.start,
        on_follow=duties.stop,
        retry_s=settings.duties_retry_s,
        replica=settings.replica_name,
    )
    await leadership.start()
    return Services(
        settings=settings,
        engine=engine,
        session_factory=factory,
        metrics=metrics,
        hub=hub,
        bus=bus,
        robots=robots,
        assignments=assignments,
        effects=effects,
        writer=writer,
        waiting=waiting,
        monitor=monitor,
        login_gate=HashingGate(
            settings.login_hash_concurrency,
            settings.login_queue_wait_s,
            settings.login_queue_max,
            settings.login_hash_nice,
        ),
        login_throttle=LoginThrottle(
            user_policy=Policy(
                settings.login_user_free_failures,
                settings.login_lockout_base_s,
                settings.login_lockout_max_s,
            ),
            client_policy=Policy(
                settings.login_client_free_failures,
                settings.login_lockout_base_s,
                settings.login_lockout_max_s,
            ),
            memory_s=settings.login_failure_memory_s,
        ),
        labelling=Labelling.build(settings),
        storage_summary=SummaryCache(settings.storage_summary_ttl_s),
        distribution=distribution,
        leadership=leadership,
    )


def build_distribution(settings: Settings, factory, effects) -> Distribution | None:
    """IHE PCD ACM alarm distribution, when an Alert Manager is configured: every session
    of `factory` then queues each alarm change for it (`backend.alarms.outbox`), on every
    replica; the sender and the listener run where the duties do (`Duties`)."""
    routing = distribution_routing.Routing.from_settings(
        settings.alert_manager, settings.alert_manager_by_ward, settings.alert_facility
    )
    if routing is None:
        return None
    sender = AlertSender(
        factory,
        routing,
        on_down=lambda session, destination, error, since: alarm_distribution.distribution_down(
            session, routing, destination, error, since
        ),
        on_up=lambda session, destination, since: alarm_distribution.distribution_up(
            session, routing, destination, since
        ),
        effects=effects,
        ack_timeout_s=settings.alert_ack_timeout_s,
        retry_s=settings.alert_retry_s,
        poll_s=settings.alert_poll_s,
        down_after_s=settings.alarm_distribution_down_s,
    )
    distribution_routing.attach(factory, routing, sender.wake)
    listener = None
    if settings.alert_status_listen:
        listen = distribution_routing.Destination.parse(
            settings.alert_status_listen, "alert_status_listen"
        )

        async def apply(status) -> str:
            async with in_event_loop(factory, effects) as unit:
                return await run_in_threadpool(
                    alarm_distribution.apply_status, unit.session, status
                )

        allowed = [d.host for d in routing.destinations()] + settings.alert_status_allowed_peers
        listener = StatusListener(listen.host, listen.port, apply, allowed)
    return Distribution(routing, sender, listener)


async def stop_services(services: Services) -> None:
    await services.leadership.stop()  # the duties stop with it
    await services.writer.stop()
    await services.waiting.stop()
    await services.bus.stop()
    services.login_gate.close()
    services.labelling.close()
    services.engine.dispose()


def _mount_frontend(app: FastAPI, frontend_dir: Path) -> None:
    """Serve the built single-page app; unknown non-API paths get index.html."""
    index = frontend_dir / "index.html"
    assets = frontend_dir / "assets"
    if assets.is_dir():
        app.mount("/assets", StaticFiles(directory=assets), name="assets")

    @app.get("/{path:path}", include_in_schema=False)
    def single_page_app(path: str) -> FileResponse:
        if path.startswith(("api/", "ws/")) or path == "metrics":
            raise HTTPException(status.HTTP_404_NOT_FOUND, "not found")
        candidate = (frontend_dir / path).resolve()
        if path and candidate.is_file() and candidate.is_relative_to(frontend_dir.resolve()):
            return FileResponse(candidate)
        if not index.is_file():
            raise HTTPException(
                status.HTTP_503_SERVICE_UNAVAILABLE,
                "frontend not built: run `make frontend` (make run does it)",
            )
        return FileResponse(index)


app = create_app()

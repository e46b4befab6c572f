"""The sender: delivers the outbox to each ward's Alert Manager over MLLP, in order, and keeps
every message until its ACK arrives.

- One MLLP connection per Alert Manager, kept open; one message in flight on it at a time (the
  Alert Manager sees the changes of an alarm in the order they happened).
- AA: delivered. AE: refused (not sent again; the alarm's audit says why). AR, no answer
  within `ack_timeout_s`, or no connection: stays pending and is sent again, with the same
  MSH-10, after `retry_s`: a restart loses none, and an Alert Manager that got a message whose
  ACK was lost recognises the repeat by its control id.
- An Alert Manager unreachable for longer than `down_after_s` (a send failing, or the idle
  probe unable to connect) is reported through `on_down`; the first delivery after it through
  `on_up` (the alarm domain raises and clears "alarm distribution down" of its wards).

Run on one replica at a time (the one that runs the alarm monitor).
"""

from __future__ import annotations

import asyncio
import contextlib
import logging
import time
from collections.abc import Callable
from dataclasses import dataclass, field
from datetime import UTC, datetime
from typing import NamedTuple

from hl7.mllp import open_hl7_connection
from sqlalchemy.orm import Session, sessionmaker
from starlette.concurrency import run_in_threadpool

from backend.distribution import queries
from backend.distribution.hl7_messages import (
    AlertReport,
    MessageError,
    build_alert_report,
    parse_ack,
)
from backend.distribution.routing import Destination, Routing
from backend.distribution.state import MESSAGE, MessageAction
from backend.models.alarms import AlarmMessage
from backend.unit_of_work import Effects, UnitOfWork, transaction, unit_of_work

log = logging.getLogger(__name__)

#: on_down(session, destination, error, since) / on_up(session, destination, down_since)
DownHook = Callable[[Session, Destination, str, datetime], None]
UpHook = Callable[[Session, Destination, datetime], None]


class Due(NamedTuple):
    message_id: int
    destination: str
    control_id: str
    payload: str | None  # None: not built yet
    report: str | None
    facility: str
    queued_at: datetime


@dataclass(slots=True)
class Outcome:
    message_id: int
    attempted_at: datetime
    code: str | None = None  # MSA-1, None: no answer
    error: str | None = None


@dataclass
class Link:
    """One Alert Manager: its connection and since when it has been unreachable."""

    destination: Destination
    reader: object | None = None
    writer: object | None = None
    failing_since: datetime | None = None
    failing_since_monotonic: float | None = None
    last_error: str = ""
    ok: bool = True  # the last attempt (send or probe) reached it
    reported_down: bool = False
    # A "distribution down" left open by an earlier run is cleared by the first delivery or
    # probe that reaches the Alert Manager.
    clear_on_reach: bool = True
    retry_at: float = 0.0
    last_probe: float = 0.0

    def close(self) -> None:
        if self.writer is not None:
            with contextlib.suppress(Exception):
                self.writer.close()
        self.reader = self.writer = None


@dataclass
class SenderStats:
    sent: int = 0
    delivered: int = 0
    refused: int = 0
    resent: int = 0
    failures: int = 0
    deliveries_ms: list[float] = field(default_factory=list)  # queued -> ACK, recent ones


class AlertSender:
    def __init__(
        self,
        session_factory: sessionmaker[Session],
        routing: Routing,
        on_down: DownHook,
        on_up: UpHook,
        effects: Effects | None = None,
        *,
        ack_timeout_s: float = 5.0,
        retry_s: float = 2.0,
        down_after_s: float = 10.0,
        probe_s: float = 5.0,
        poll_s: float = 0.5,
        batch: int = 200,
    ) -> None:
        self._factory = session_factory
        self.routing = routing
        self._on_down = on_down
        self._on_up = on_up
        self._effects = effects
        self.ack_timeout_s = ack_timeout_s
        self.retry_s = retry_s
        self.down_after_s = down_after_s
        self.probe_s = probe_s
        self.poll_s = poll_s
        self.batch = batch
        self.links = {d: Link(d) for d in routing.destinations()}
        self.stats = SenderStats()
        self._bell = asyncio.Event()
        self._loop: asyncio.AbstractEventLoop | None = None
        self._task: asyncio.Task | None = None

    # -- life ------------------------------------------------------------------------------
    def start(self) -> None:
        self._loop = asyncio.get_running_loop()
        self._task = asyncio.create_task(self._run(), name="alarm-distribution")

    async def stop(self) -> None:
        if self._task is not None:
            self._task.cancel()
            with contextlib.suppress(asyncio.CancelledError):
                await self._task
        for link in self.links.values():
            link.close()

    def wake(self) -> None:
        """Ring the bell: a message was queued (safe from any thread)."""
        loop = self._loop
        if loop is None or loop.is_closed():
            return
        try:
            running = asyncio.get_running_loop()
        except RuntimeError:
            running = None
        if running is loop:
            self._bell.set()
        else:
            loop.call_soon_threadsafe(self._bell.set)

    async def _run(self) -> None:
        while True:
            try:
                busy = await self.deliver_once()
                await self._probe_idle()
            except asyncio.CancelledError:
                raise
            except Exception:
                log.exception("alarm distribution: delivery round failed")
                busy = False
            if not busy:
                with contextlib.suppress(TimeoutError):
                    await asyncio.wait_for(self._bell.wait(), self.poll_s)
                self._bell.clear()

    # -- one round ---------------------------------------------------------------------------
    def _due(self) -> list[Due]:
        with self._factory() as session:
            return [
                Due(
                    m.id, m.destination, m.control_id, m.payload, m.report, m.facility, m.created_at
                )
                for m in queries.due(session, self.batch)
            ]

    def _build(self, due: list[Due]) -> list[Due]:
        """Build the ORU^R40 of each message not built yet and keep it (one short transaction):
        a resend is the same message. One that does not validate is refused, never sent."""
        built: dict[int, str] = {}
        invalid: dict[int, str] = {}
        for row in due:
            if row.payload is not None:
                continue
            try:
                report = AlertReport.from_json(row.report or "")
                built[row.message_id] = build_alert_report(report, row.facility)
            except (MessageError, ValueError, TypeError, KeyError) as error:
                invalid[row.message_id] = f"not a valid HL7 v2.6 ORU^R40: {_describe(error)}"
        if not built and not invalid:
            return due
        with transaction(self._factory) as session:
            for message in queries.by_ids(session, [*built, *invalid]):
                if message.id in built:
                    message.payload = built[message.id]
                elif message.status == MESSAGE.initial:
                    message.last_error = invalid[message.id]
                    MESSAGE.act(message, MessageAction.REFUSE)
                    log.error(
                        "alarm distribution: message %s %s", message.control_id, message.last_error
                    )
        return [
            row if row.message_id not in built else row._replace(payload=built[row.message_id])
            for row in due
            if row.message_id not in invalid
        ]

    async def deliver_once(self) -> bool:
        """Send what is due; True if anything was delivered (look again at once)."""
        due = await run_in_threadpool(self._due)
        if not due:
            return False
        if any(row.payload is None for row in due):
            due = await run_in_threadpool(self._build, due)
        by_destination: dict[str, list] = {}
        for row in due:
            by_destination.setdefault(row[1], []).append(row)
        outcomes: list[Outcome] = []
        now = time.monotonic()
        for destination_text, rows in by_destination.items():
            link = self._link(destination_text)
            if link is None or now < link.retry_at:
                continue
            for message_id, _, control_id, payload, _, _, queued_at in rows:
                outcome = await self._send(link, message_id, control_id, payload)
                outcomes.append(outcome)
                if outcome.code in ("AA", "CA"):
                    latency = (outcome.attempted_at - queued_at).total_seconds() * 1000
                    self.stats.deliveries_ms = self.stats.deliveries_ms[-999:] + [latency]
                if outcome.code is None or outcome.code in ("AR", "CR"):
                    link.retry_at = time.monotonic() + self.retry_s
                    break  # in order: nothing after it goes first
        if outcomes:
            await run_in_threadpool(self._record, outcomes)
        await self._report_links()
        return any(o.code in ("AA", "CA", "AE", "CE") for o in outcomes)

    def _link(self, destination_text: str) -> Link | None:
        for destination, link in self.links.items():
            if str(destination) == destination_text:
                return link
        try:  # queued for an Alert Manager no longer in the settings: still delivered
            destination = Destination.parse(destination_text)
        except ValueError:
            return None
        return self.links.setdefault(destination, Link(destination))

    async def _connect(self, link: Link) -> None:
        if link.writer is not None and not link.reader.at_eof():
            return
        link.close()
        destination = link.destination
        link.reader, link.writer = await asyncio.wait_for(
            open_hl7_connection(destination.host, destination.port), self.ack_timeout_s
        )

    async def _send(self, link: Link, message_id: int, control_id: str, payload: str) -> Outcome:
        attempted_at = datetime.now(UTC)
        try:
            await self._connect(link)
            link.writer.writeblock(payload.encode())
            await link.writer.drain()
            self.stats.sent += 1
            while True:
                block = await asyncio.wait_for(link.reader.readblock(), self.ack_timeout_s)
                ack = parse_ack(block.decode(errors="replace"))
                if ack.control_id == control_id:
                    break
                log.warning(
                    "alarm distribution: ACK for %s while waiting for %s (ignored)",
                    ack.control_id,
                    control_id,
                )
        except (
            OSError,
            TimeoutError,
            asyncio.IncompleteReadError,
            ValueError,
            MessageError,
        ) as error:
            link.close()
            reason = _describe(error)
            self._failed(link, reason)
            self.stats.failures += 1
            return Outcome(message_id, attempted_at, None, reason)
        self._succeeded(link)
        if ack.accepted:
            self.stats.delivered += 1
        elif not ack.rejected:
            self.stats.refused += 1
        return Outcome(message_id, attempted_at, ack.code, ack.text or None)

    def _record(self, outcomes: list[Outcome]) -> None:
        with transaction(self._factory) as session:
            for outcome in outcomes:
                message = session.get(AlarmMessage, outcome.message_id)
                if message is None or message.status != MESSAGE.initial:
                    continue
                message.attempts += 1
                if message.attempts > 1:
                    self.stats.resent += 1
                message.last_attempt_at = outcome.attempted_at
                message.ack_code = outcome.code
                message.last_error = outcome.error
                if outcome.code in ("AA", "CA"):
                    MESSAGE.act(message, MessageAction.ACKNOWLEDGE)
                    message.acked_at = datetime.now(UTC)
                elif outcome.code in ("AE", "CE"):
                    MESSAGE.act(message, MessageAction.REFUSE)
                    log.error(
                        "alarm distribution: %s refused message %s: %s",
                        message.destination,
                        message.control_id,
                        outcome.error,
                    )

    # -- reachability ------------------------------------------------------------------------
    def _failed(self, link: Link, reason: str) -> None:
        if link.failing_since is None:
            link.failing_since = datetime.now(UTC)
            link.failing_since_monotonic = time.monotonic()
            log.warning(
                "alarm distribution: Alert Manager %s unreachable: %s", link.destination, reason
            )
        link.ok = False
        link.last_error = reason

    def _succeeded(self, link: Link) -> None:
        link.ok = True
        link.last_error = ""

    async def _report_links(self) -> None:
        now = time.monotonic()
        for link in self.links.values():
            if link.ok:
                if link.reported_down or link.clear_on_reach:
                    cleared = await self._in_unit(self._on_up, link.destination, link.failing_since)
                    if cleared:
                        log.info(
                            "alarm distribution: Alert Manager %s reachable again",
                            link.destination,
                        )
                    link.reported_down = link.clear_on_reach = False
                link.failing_since = link.failing_since_monotonic = None
            elif (
                link.failing_since_monotonic is not None
                and not link.reported_down
                and now - link.failing_since_monotonic >= self.down_after_s
            ):
                await self._in_unit(
                    self._on_down,
                    link.destination,
                    link.last_error,
                    link.failing_since,
                )
                link.reported_down = True

    async def _in_unit(self, hook, *args):
        """Run a hook in its own unit of work; the alarms it changes reach the boards."""
        unit, result = await run_in_threadpool(self._hook_unit, hook, *args)
        await unit.run_after_commit(self._effects)
        return result

    def _hook_unit(self, hook, *args) -> tuple[UnitOfWork, object]:
        with unit_of_work(self._factory) as unit:
            result = hook(unit.session, *args)
        return unit, result

    async def _probe_idle(self) -> None:
        """An Alert Manager with nothing to send is still checked: nurses must know before
        the next fall that their phones would not ring."""
        now = time.monotonic()
        for link in self.links.values():
            period = self.probe_s if link.ok else self.retry_s
            if now - link.last_probe < period or now < link.retry_at:
                continue
            link.last_probe = now
            try:
                await self._connect(link)
            except (OSError, TimeoutError) as error:
                link.close()
                self._failed(link, _describe(error))
                continue
            if link.reader.at_eof():
                link.close()
                self._failed(link, "connection closed by the Alert Manager")
                continue
            if not link.ok and not await run_in_threadpool(self._has_pending, link):
                self._succeeded(link)  # with messages waiting, only a delivery proves it
        await self._report_links()

    def _has_pending(self, link: Link) -> bool:
        with self._factory() as session:
            return bool(queries.pending_by_ward(session, str(link.destination)))

    def status(self) -> list[dict]:
        return [
            {
                "destination": str(link.destination),
                "connected": link.writer is not None,
                "down": link.reported_down,
                "failing_since": link.failing_since.isoformat() if link.failing_since else None,
                "last_error": link.last_error or None,
            }
            for link in self.links.values()
        ]


def _describe(error: BaseException) -> str:
    if isinstance(error, TimeoutError):
        return "no answer (timed out)"
    if isinstance(error, asyncio.IncompleteReadError):
        return "connection closed by the Alert Manager"
    return f"{type(error).__name__}: {error}" if str(error) else type(error).__name__

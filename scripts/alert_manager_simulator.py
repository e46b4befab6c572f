"""A small local Alert Manager (IHE PCD ACM) for the demo and the tests: it receives Vigil's
ORU^R40 over MLLP, prints what a nurse's phone would show, answers each with an ACK and, like a
real alarm distribution system, reports back over MLLP (ORA^R41) that the alert was delivered
to the ward's phone, read and, optionally, accepted.

    python -m scripts.alert_manager_simulator --listen 127.0.0.1:2575 \
        --vigil 127.0.0.1:2576 [--accept-after 20] [--ward-phone "ward-a=Anna Berg"]

It is a simulator: no real phone rings. `make run` starts one and points the backend at it.
"""

from __future__ import annotations

import argparse
import asyncio
import contextlib
import logging
from collections.abc import Callable
from dataclasses import dataclass, field
from datetime import UTC, datetime

from hl7.mllp import open_hl7_connection, start_hl7_server

from backend.distribution.hl7_messages import (
    Change,
    Disposition,
    MessageError,
    ReceivedReport,
    ack_for,
    build_alert_status,
    parse_ack,
    parse_alert_report,
)
from backend.distribution.routing import Destination

log = logging.getLogger("vigil.alert_manager_simulator")

#: The changes a phone rings for; the others update what it shows.
RINGS = {Change.RAISED, Change.ESCALATED, Change.MISSED, Change.REALARMED}


@dataclass(frozen=True, slots=True)
class Phone:
    clinician_id: str
    given: str
    family: str

    @property
    def name(self) -> str:
        return f"{self.given} {self.family}".strip()

    @property
    def device(self) -> str:
        return f"{self.given}'s phone"

    @classmethod
    def parse(cls, name: str, index: int = 1) -> Phone:
        given, _, family = name.strip().partition(" ")
        return cls(f"RN{index:03d}", given or "Nurse", family)


DEFAULT_PHONE = Phone("RN001", "Anna", "Berg")


@dataclass
class AlertManagerSimulator:
    """`answer`: the ACK code it gives (AA; AE refuses; None: never answers, as a hung
    Alert Manager). `deliver_after_s`/`read_after_s`/`accept_after_s`: when, after an alert
    that rings, it reports delivered / read / accepted to `vigil` (None: never)."""

    host: str = "127.0.0.1"
    port: int = 0
    vigil: Destination | None = None
    phones: dict[str, Phone] = field(default_factory=dict)
    answer: str | None = "AA"
    deliver_after_s: float | None = 0.3
    read_after_s: float | None = 1.0
    accept_after_s: float | None = None
    show: Callable[[str], None] = print
    received: list[ReceivedReport] = field(default_factory=list)  # one per control id
    arrivals: list[str] = field(default_factory=list)  # every control id, repeats included
    statuses_sent: list[tuple[str, Disposition, str]] = field(default_factory=list)
    status_answers: list[str] = field(default_factory=list)  # Vigil's ACK codes
    _server: asyncio.AbstractServer | None = None
    _tasks: set[asyncio.Task] = field(default_factory=set)
    _writers: set = field(default_factory=set)

    def phone_of(self, ward: str) -> Phone:
        return self.phones.get(ward, DEFAULT_PHONE)

    async def start(self) -> None:
        self._server = await start_hl7_server(self._client, self.host, self.port)
        self.port = self._server.sockets[0].getsockname()[1]

    async def stop(self) -> None:
        for task in list(self._tasks):
            task.cancel()
        for writer in list(self._writers):
            writer.close()
        self._writers.clear()
        if self._server is not None:
            self._server.close()
            with contextlib.suppress(Exception):
                await self._server.wait_closed()
            self._server = None

    async def _client(self, reader, writer) -> None:
        self._writers.add(writer)
        try:
            while not reader.at_eof():
                try:
                    block = await reader.readblock()
                except asyncio.IncompleteReadError:
                    break
                await self._receive(writer, block.decode(errors="replace"))
        except (OSError, ValueError) as error:
            log.warning("connection: %s", error)
        finally:
            self._writers.discard(writer)
            writer.close()

    async def _receive(self, writer, text: str) -> None:
        try:
            report = parse_alert_report(text)
        except MessageError as error:
            self.show(f"[alert manager] refused a message: {error}")
            writer.writeblock(ack_for(text, "AE", str(error), application="ACM").encode())
            await writer.drain()
            return
        self.arrivals.append(report.control_id)
        repeat = any(r.control_id == report.control_id for r in self.received)
        if self.answer is None:
            if not repeat:
                self.received.append(report)
            return  # hung: it holds the message but never answers
        if not repeat:
            self.received.append(report)
            self._display(report)
        writer.writeblock(ack_for(text, self.answer, application="ACM").encode())
        await writer.drain()
        if not repeat and report.change in RINGS and self.vigil is not None:
            task = asyncio.create_task(self._report_back(report))
            self._tasks.add(task)
            task.add_done_callback(self._tasks.discard)

    def _display(self, report: ReceivedReport) -> None:
        phone = self.phone_of(report.ward)
        ring = "RING " if report.change in RINGS else "     "
        at = datetime.now(UTC).strftime("%H:%M:%S")
        self.show(
            f"[{phone.device}] {at} {ring}{report.priority:>2} alarm {report.alarm_id} "
            f"{report.change.value}: {report.text}"
        )

    async def _report_back(self, report: ReceivedReport) -> None:
        plan = [
            (self.deliver_after_s, Disposition.DELIVERED),
            (self.read_after_s, Disposition.READ),
            (self.accept_after_s, Disposition.ACCEPTED),
        ]
        waited = 0.0
        for after, disposition in plan:
            if after is None:
                continue
            await asyncio.sleep(max(0.0, after - waited))
            waited = max(waited, after)
            await self.send_status(report, disposition)

    async def send_status(self, report: ReceivedReport, disposition: Disposition) -> str:
        """Report one disposition to Vigil; returns Vigil's ACK code."""
        assert self.vigil is not None
        phone = self.phone_of(report.ward)
        message = build_alert_status(
            report.control_id,
            report.alarm_id,
            disposition,
            phone.clinician_id,
            phone.family,
            phone.given,
            f"PHONE-{phone.clinician_id}",
            phone.device,
            datetime.now(UTC),
        )
        code = "no answer"
        try:
            reader, writer = await open_hl7_connection(self.vigil.host, self.vigil.port)
            try:
                writer.writeblock(message.encode())
                await writer.drain()
                block = await asyncio.wait_for(reader.readblock(), 5.0)
                code = parse_ack(block.decode(errors="replace")).code
            finally:
                writer.close()
        except (OSError, TimeoutError, asyncio.IncompleteReadError, MessageError) as error:
            code = f"error: {error}"
        self.statuses_sent.append((report.control_id, disposition, code))
        self.status_answers.append(code)
        self.show(
            f"[{phone.device}] alarm {report.alarm_id} {disposition.value} by {phone.name} "
            f"(Vigil answered {code})"
        )
        return code


def _phones(values: list[str]) -> dict[str, Phone]:
    phones = {}
    for index, value in enumerate(values, start=1):
        ward, separator, name = value.partition("=")
        if not separator or not ward or not name:
            raise SystemExit(f"--ward-phone: expected ward=Given Family, got {value!r}")
        phones[ward] = Phone.parse(name, index)
    return phones


async def _serve(args: argparse.Namespace) -> None:
    listen = Destination.parse(args.listen, "--listen")
    simulator = AlertManagerSimulator(
        host=listen.host,
        port=listen.port,
        vigil=Destination.parse(args.vigil, "--vigil") if args.vigil else None,
        phones=_phones(args.ward_phone),
        accept_after_s=args.accept_after,
        show=lambda line: print(line, flush=True),
    )
    await simulator.start()
    print(
        f"[alert manager] simulated IHE PCD ACM Alert Manager on {listen.host}:{simulator.port}"
        f"{'; dispositions to Vigil at ' + args.vigil if args.vigil else ''} (no real phone rings)",
        flush=True,
    )
    try:
        await asyncio.Event().wait()
    finally:
        await simulator.stop()


def main(argv: list[str] | None = None) -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--listen", default="127.0.0.1:2575", help="host:port for ORU^R40")
    parser.add_argument("--vigil", default=None, help="Vigil's ORA^R41 listener, host:port")
    parser.add_argument(
        "--accept-after",
        type=float,
        default=None,
        help="the phone accepts each ringing alert after this many seconds (acknowledges it)",
    )
    parser.add_argument(
        "--ward-phone",
        action="append",
        default=[],
        help='whose phone a ward rings: "ward-a=Anna Berg" (repeatable)',
    )
    args = parser.parse_args(argv)
    with contextlib.suppress(KeyboardInterrupt):
        asyncio.run(_serve(args))


if __name__ == "__main__":
    main()

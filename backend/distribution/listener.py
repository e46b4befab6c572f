"""The MLLP listener for what the Alert Manager reports back (ORA^R41, IHE PCD-05): each
message is parsed, handed to `apply` (the alarm domain, in a unit of work) and answered with an
ACK: AA when recorded, AE naming the field when Vigil cannot read it or it names no message Vigil
sent. Connections from hosts other than the configured Alert Managers (and
`allowed_peers`) are closed unanswered."""

from __future__ import annotations

import asyncio
import contextlib
import ipaddress
import logging
import socket
from collections.abc import Awaitable, Callable

from hl7.mllp import start_hl7_server

from backend.distribution.hl7_messages import (
    AlertStatus,
    MessageError,
    ack_for,
    parse_alert_status,
)

log = logging.getLogger(__name__)

#: apply(status) -> what was recorded (for the log); raises MessageError to answer AE
Apply = Callable[[AlertStatus], Awaitable[str]]


def _addresses(host: str) -> set[str]:
    try:
        return {info[4][0] for info in socket.getaddrinfo(host, None)}
    except OSError:
        return set()


class StatusListener:
    def __init__(self, host: str, port: int, apply: Apply, allowed_hosts: list[str]) -> None:
        self.host = host
        self.port = port
        self._apply = apply
        self._allowed: set[str] = set()
        for allowed in allowed_hosts:
            self._allowed |= _addresses(allowed)
        self._server: asyncio.AbstractServer | None = None
        self.received = 0
        self.refused_peers = 0

    async def start(self) -> None:
        self._server = await start_hl7_server(self._client, self.host, self.port)
        self.port = self._server.sockets[0].getsockname()[1]
        log.info("alarm distribution: listening for ORA^R41 on %s:%s", self.host, self.port)

    async def stop(self) -> None:
        if self._server is not None:
            self._server.close()
            with contextlib.suppress(Exception):
                await self._server.wait_closed()

    def _peer_allowed(self, peer: str) -> bool:
        if not self._allowed:
            return True
        if peer in self._allowed:
            return True
        with contextlib.suppress(ValueError):  # ::ffff:127.0.0.1 and 127.0.0.1 are one host
            mapped = ipaddress.ip_address(peer)
            if isinstance(mapped, ipaddress.IPv6Address) and mapped.ipv4_mapped:
                return str(mapped.ipv4_mapped) in self._allowed
        return False

    async def _client(self, reader, writer) -> None:
        peer = (writer.get_extra_info("peername") or ("?",))[0]
        if not self._peer_allowed(peer):
            self.refused_peers += 1
            log.warning(
                "alarm distribution: ORA^R41 connection from %s refused (not an Alert "
                "Manager of the settings)",
                peer,
            )
            writer.close()
            return
        try:
            while not reader.at_eof():
                try:
                    block = await reader.readblock()
                except asyncio.IncompleteReadError:
                    break
                text = block.decode(errors="replace")
                await self._answer(writer, text)
        except (OSError, ValueError) as error:
            log.warning("alarm distribution: status connection from %s: %s", peer, error)
        finally:
            writer.close()

    async def _answer(self, writer, text: str) -> None:
        self.received += 1
        try:
            status = parse_alert_status(text)
            recorded = await self._apply(status)
        except MessageError as error:
            log.warning("alarm distribution: status refused: %s", error)
            try:
                answer = ack_for(text, "AE", str(error))
            except MessageError:
                return  # not HL7 at all: nothing to acknowledge
        else:
            log.info("alarm distribution: %s", recorded)
            answer = ack_for(text, "AA")
        writer.writeblock(answer.encode())
        await writer.drain()

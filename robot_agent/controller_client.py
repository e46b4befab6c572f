"""Reference client of the local command socket (docs/robot_agent.md): what a robot's motion
controller does with the behaviour lines.

    python -m robot_agent.controller_client --socket var/robot.sock          print every line
    python -m robot_agent.controller_client --socket var/robot.sock --reset  local reset

A real controller maps `state` to motion: transporting -> drive, paused -> hold position,
emergency_stop -> stop and call for help, detection_degraded -> slow or stop as the reason says.
"""

from __future__ import annotations

import argparse
import json
import socket
import sys
from collections.abc import Iterator
from pathlib import Path

MOTION = {
    "transporting": "drive",
    "paused": "hold position",
    "emergency_stop": "STOP, call for help, stay with the patient",
    "detection_degraded": "slow down or stop (see reason)",
}


def connect(path: Path, timeout: float | None = None) -> socket.socket:
    sock = socket.socket(socket.AF_UNIX, socket.SOCK_STREAM)
    sock.settimeout(timeout)
    sock.connect(str(path))
    return sock


def lines(sock: socket.socket) -> Iterator[dict]:
    """Every JSON line the agent sends, as a dict (the first one is the current state)."""
    buffer = b""
    while chunk := sock.recv(65536):
        buffer += chunk
        while b"\n" in buffer:
            line, buffer = buffer.split(b"\n", 1)
            if line.strip():
                yield json.loads(line)


def reset(path: Path, timeout: float = 5.0) -> dict:
    """Ask the agent for a local reset of an emergency stop; its reply."""
    with connect(path, timeout) as sock:
        sock.sendall(b'{"command":"reset"}\n')
        for line in lines(sock):
            if "reset" in line or "error" in line:
                return line
    raise ConnectionError("the agent closed the socket without answering the reset")


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(prog="controller_client", description=__doc__.split("\n")[0])
    parser.add_argument("--socket", type=Path, required=True, help="the agent's local_socket")
    parser.add_argument("--reset", action="store_true", help="reset an emergency stop")
    args = parser.parse_args(argv)
    try:
        if args.reset:
            reply = reset(args.socket)
            print(json.dumps(reply))
            return 0 if reply.get("reset") else 1
        with connect(args.socket) as sock:
            for line in lines(sock):
                motion = MOTION.get(line.get("state"), "unknown state: stop")
                print(json.dumps(line), "->", motion, flush=True)
    except (FileNotFoundError, ConnectionRefusedError) as error:
        print(
            f"controller_client: socket {args.socket}: agent not running ({error})", file=sys.stderr
        )
        return 2
    except KeyboardInterrupt:
        pass
    return 0


if __name__ == "__main__":
    sys.exit(main())

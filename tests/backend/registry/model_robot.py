"""A minimal robot process for the rollout tests (imports only vigil, websockets and httpx).

It speaks the robot protocol: hello, then on `assign_model` downloads the file with its robot
token, checks the sha256 of the assignment, loads it with the manifest's sha256 check, and
reports the version it now runs in a heartbeat. Run: python -m tests.backend.registry.model_robot
--url ws://host:port/ws/robot --robot-id R --token T --dir DIR
"""

from __future__ import annotations

import argparse
import asyncio
import contextlib
import hashlib
import json
import sys
import time
from pathlib import Path

import httpx
import websockets

from vigil.model_file import MANIFEST_NAME, ModelManifest, load_classifier
from vigil.protocol import Heartbeat, Hello, ModelAssignment, server_message_adapter


async def run(args) -> None:
    running: str | None = None
    async with websockets.connect(args.url) as socket:
        hello = Hello(robot_id=args.robot_id, token=args.token, agent_version="test-robot")
        await socket.send(hello.model_dump_json())
        while True:
            message = server_message_adapter.validate_json(await socket.recv())
            if not isinstance(message, ModelAssignment) or message.shadow:
                continue
            response = httpx.get(message.url, headers={
                "X-Robot-Id": args.robot_id, "Authorization": f"Bearer {args.token}"})  # fmt: skip
            response.raise_for_status()
            if hashlib.sha256(response.content).hexdigest() != message.sha256:
                print(f"REJECTED {message.version}: sha256 mismatch", flush=True)
                continue
            manifest = ModelManifest.model_validate(message.manifest)
            directory = Path(args.dir) / message.version
            directory.mkdir(parents=True, exist_ok=True)
            (directory / manifest.file).write_bytes(response.content)
            (directory / MANIFEST_NAME).write_text(json.dumps(message.manifest))
            load_classifier(directory)  # checks the manifest's sha256 again before use
            running = message.version
            await socket.send(Heartbeat(ts=time.time(), running_model=running).model_dump_json())
            print(f"RUNNING {running}", flush=True)


def main() -> int:
    parser = argparse.ArgumentParser()
    for name in ("--url", "--robot-id", "--token", "--dir"):
        parser.add_argument(name, required=True)
    with contextlib.suppress(KeyboardInterrupt):
        asyncio.run(run(parser.parse_args()))
    return 0


if __name__ == "__main__":
    sys.exit(main())

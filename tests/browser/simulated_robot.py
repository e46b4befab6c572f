"""A tiny robot for browser tests: speaks vigil.protocol over a real websocket.

The skeletons are GENERATED (a stick figure standing, then tipping over); they only drive the
alarm pipeline and the replay view, never a claim about detection quality.
"""

from __future__ import annotations

import json
import math
import time

from websockets.sync.client import ClientConnection, connect

from vigil.protocol import FrameBatch, FrameRecord, Hello, TransportStart

# A standing stick figure in BODY_25 order: (x, y) in pixels, y grows downwards.
_STANDING = [
    (0, -160),
    (0, -140),
    (-20, -140),
    (-28, -105),
    (-32, -70),
    (20, -140),
    (28, -105),
    (32, -70),
    (0, -70),
    (-12, -70),
    (-14, -35),
    (-15, 0),
    (12, -70),
    (14, -35),
    (15, 0),
    (-5, -165),
    (5, -165),
    (-10, -162),
    (10, -162),
    (22, 2),
    (26, 2),
    (12, 2),
    (-22, 2),
    (-26, 2),
    (-12, 2),
]


def posed_keypoints(tilt_rad: float, x0: float = 320.0, y0: float = 400.0) -> list[list[float]]:
    """The stick figure rotated about its feet by tilt_rad (0 standing, pi/2 lying)."""
    c, s = math.cos(tilt_rad), math.sin(tilt_rad)
    return [[x0 + x * c - y * s, y0 + x * s + y * c, 0.9] for x, y in _STANDING]


def fall_frames(
    start_seq: int,
    t0: float,
    transport_id: str,
    fps: float = 10.0,
    normal_s: float = 2.0,
    fall_s: float = 1.0,
    lying_s: float = 2.0,
    model_version: str = "sim-1",
    threshold: float = 0.6,
    delay_ms: int = 300,
) -> list[FrameRecord]:
    """Normal walking, a fall, then lying: per-frame Emergency scores and decisions as a robot's
    classifier with delay filter would send them."""
    frames = []
    n_normal, n_fall, n_lying = (round(x * fps) for x in (normal_s, fall_s, lying_s))
    held = 0.0
    for i in range(n_normal + n_fall + n_lying):
        if i < n_normal:
            tilt, p = 0.0, 0.05 + 0.03 * math.sin(i)
        elif i < n_normal + n_fall:
            progress = (i - n_normal + 1) / n_fall
            tilt, p = progress * math.pi / 2, 0.2 + 0.75 * progress
        else:
            tilt, p = math.pi / 2, 0.95
        held = held + 1000 / fps if p >= threshold else 0.0
        decision = "emergency" if p >= threshold and held > delay_ms else "normal"
        frames.append(
            FrameRecord(
                seq=start_seq + i,
                ts=t0 + i / fps,
                transport_id=transport_id,
                keypoints=posed_keypoints(tilt),
                depth=[2.5] * 25,
                decision=decision,
                scores={"normal": round(1 - p, 4), "emergency": round(p, 4)},
                model_version=model_version,
                threshold=threshold,
                delay_ms=delay_ms,
            )
        )
    return frames


class SimulatedRobot:
    def __init__(
        self, ws_url: str, robot_id: str, token: str, inputs: list[str] | None = None
    ) -> None:
        """`inputs`: what its hello says it feeds (None: an older agent that says nothing)."""
        self.ws_url, self.robot_id, self.token = ws_url, robot_id, token
        self.inputs = inputs
        self.connection: ClientConnection | None = None
        self.welcome: dict | None = None

    def __enter__(self) -> SimulatedRobot:
        self._context = connect(self.ws_url, open_timeout=10)
        self.connection = self._context.__enter__()
        self.send(
            Hello(
                robot_id=self.robot_id,
                token=self.token,
                running_model="sim-1",
                inputs=self.inputs,
            )
        )
        self.welcome = self.receive("welcome")
        return self

    def __exit__(self, *exc) -> None:
        if self.connection is not None:
            self._context.__exit__(*exc)
            self.connection = None

    def send(self, message) -> None:
        self.connection.send(message.model_dump_json())

    def receive(self, expected_type: str, timeout: float = 10.0) -> dict:
        deadline = time.monotonic() + timeout
        while True:
            message = json.loads(
                self.connection.recv(timeout=max(0.01, deadline - time.monotonic()))
            )
            if message.get("type") == expected_type:
                return message
            if message.get("type") == "error":
                raise AssertionError(f"server error: {message}")

    def start_transport(self, transport_id: str, patient: str, location: str) -> None:
        self.send(
            TransportStart(
                transport_id=transport_id,
                mode="walking",
                patient=patient,
                location=location,
                ts=time.time(),
            )
        )

    def send_batch(self, frames: list[FrameRecord]) -> None:
        self.send(FrameBatch(frames=frames))

    def wait_ack(self, seq: int) -> None:
        while self.receive("ack")["seq"] < seq:
            pass

    def stream(self, frames: list[FrameRecord], batch: int = 10, realtime: bool = False) -> int:
        """Send frames in batches; returns the last sequence number the server acknowledged."""
        last_ack = -1
        for i in range(0, len(frames), batch):
            chunk = frames[i : i + batch]
            self.send(FrameBatch(frames=chunk))
            while last_ack < chunk[-1].seq:
                last_ack = self.receive("ack")["seq"]
            if realtime:
                time.sleep(len(chunk) / 10)
        return last_ack

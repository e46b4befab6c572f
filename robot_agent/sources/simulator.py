"""GENERATED transports (vigil.synthetic) as a keypoint source, for demos and load.

Each Observation holds everyone the simulated pose estimator sees (shuffled, no identities),
the patient's fine label as ``truth`` and the patient's position in ``people`` as
``patient_hint`` (ground truth for tests; the tracker does not use it). People carry their
depth in metres already, so there is no depth image. With ``render_rgb`` a grey 640x480 image
with the patient's ArUco marker (DICT_4X4_50) drawn on the chest is attached, so marker
selection runs end to end. Everything it yields is generated data.
"""

from __future__ import annotations

from collections.abc import Iterator, Sequence

import cv2
import numpy as np

from robot_agent.sources.pacing import Pacer
from vigil.observation import Observation
from vigil.synthetic import FPS, IMAGE_HEIGHT, IMAGE_WIDTH, GeneratedTransport, generate_transport

MARKER_DICTIONARY = cv2.aruco.DICT_4X4_50
MIN_MARKER_PX = 24  # smaller markers are drawn at this size so the detector can read them


def render_marker_image(
    transport: GeneratedTransport, t: int, marker_id: int = 0, background: int = 90
) -> np.ndarray:
    """A BGR image (GENERATED) with only the patient's chest marker drawn, if visible."""
    image = np.full((IMAGE_HEIGHT, IMAGE_WIDTH, 3), background, np.uint8)
    u, v, side = transport.marker_px[t]
    if not np.isfinite([u, v, side]).all():
        return image
    size = int(max(round(side), MIN_MARKER_PX))
    marker = cv2.aruco.generateImageMarker(
        cv2.aruco.getPredefinedDictionary(MARKER_DICTIONARY), marker_id, size
    )
    quiet = max(size // 4, 2)  # white border the detector needs around the marker
    tile = cv2.copyMakeBorder(marker, quiet, quiet, quiet, quiet, cv2.BORDER_CONSTANT, value=255)
    x0, y0 = int(round(u)) - tile.shape[1] // 2, int(round(v)) - tile.shape[0] // 2
    x1, y1 = x0 + tile.shape[1], y0 + tile.shape[0]
    if x0 < 0 or y0 < 0 or x1 > IMAGE_WIDTH or y1 > IMAGE_HEIGHT:
        return image
    image[y0:y1, x0:x1] = tile[:, :, None]
    return image


class SimulatorSource:
    """Keypoint source over GENERATED transports.

    mode: walking, rollator or wheelchair; n_people: 1-5 in view; events: see
    ``vigil.synthetic.EVENTS_BY_LOCOMOTION`` (None: chosen by the seed); transports: how many
    transports to play back to back (seeds seed, seed+1, ...; None: endless); speed: 1 real
    time, 0 as fast as possible.
    """

    fps = FPS
    generated = True

    def __init__(
        self,
        mode: str = "walking",
        seed: int = 0,
        duration_s: float = 30.0,
        n_people: int = 3,
        events: Sequence[str] | None = None,
        transports: int | None = 1,
        speed: float = 1.0,
        render_rgb: bool = False,
        marker_id: int = 0,
    ) -> None:
        self.mode = mode
        self.seed = seed
        self.duration_s = duration_s
        self.n_people = n_people
        self.events = events
        self.transports = transports
        self.speed = speed
        self.render_rgb = render_rgb
        self.marker_id = marker_id
        self.name = f"simulator:{mode} (generated)"
        self.transport(0)  # bad parameters fail here, not in the middle of a run

    def transport(self, number: int) -> GeneratedTransport:
        return generate_transport(
            self.mode, self.seed + number, self.duration_s, self.events, self.n_people
        )

    def __iter__(self) -> Iterator[Observation]:
        pacer = Pacer(self.speed)
        number, index, offset = 0, 0, 0.0
        while self.transports is None or number < self.transports:
            transport = self.transport(number)
            for t in range(transport.n_frames):
                timestamp = offset + t / transport.fps
                pacer.wait(timestamp)
                ids = transport.detection_ids(t)
                patient = transport.patient_index
                hint = ids.index(patient) if patient in ids else None
                people = transport.detections(t)
                for person in people:
                    person.timestamp = timestamp
                yield Observation(
                    timestamp=timestamp,
                    people=people,
                    index=index,
                    rgb=render_marker_image(transport, t, self.marker_id)
                    if self.render_rgb
                    else None,
                    truth=transport.labels[t],
                    patient_hint=hint,
                )
                index += 1
            offset += transport.n_frames / transport.fps
            number += 1

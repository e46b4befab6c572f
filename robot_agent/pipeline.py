"""One robot's frame path: source observation -> patient -> depth -> classification -> outbox.

Everything here runs between two camera frames on the agent's event loop; a model swap
(`swap_model`) is also called there, so it always happens between two frames. The new model's
feature history is warmed up with the frames of the current transport it missed.
"""

from __future__ import annotations

import json
import logging
import math
import time
from collections import deque
from collections.abc import Callable
from dataclasses import dataclass
from typing import Protocol

import numpy as np

from robot_agent.outbox import Outbox, Priority
from vigil.classes import Decision, TransportMode
from vigil.depth import sample_depth
from vigil.features import NEEDS_FLOOR
from vigil.floor import CameraMount, floor_measures
from vigil.observation import Observation
from vigil.protocol import FrameRecord, TransportEnd, TransportStart
from vigil.runtime import Classification, FrameClassifier
from vigil.skeleton import SkeletonFrame, empty_keypoints
from vigil.taxonomy import DEFAULT_TAXONOMY
from vigil.tracking import PatientTracker as TrackingPatientTracker

log = logging.getLogger(__name__)

#: model_version of frames whose decision is the generator's ground truth, not a model's.
GROUND_TRUTH_VERSION = "generated-ground-truth"
WARMUP_FRAMES = 150  # frames of the current transport replayed into a newly swapped-in model


class TrackedPatient(Protocol):
    patient: SkeletonFrame | None  # None when the patient is not seen in this observation


class PatientTracker(Protocol):
    def reset(self) -> None: ...

    def update(self, observation: Observation) -> TrackedPatient: ...


DepthSampler = Callable[[np.ndarray, np.ndarray, float], np.ndarray]
"""(depth_image, keypoints (25, 3), depth_scale_mm) -> depth (25,) metres, NaN where unknown."""


@dataclass(frozen=True, slots=True)
class FrameResult:
    seq: int
    decision: Decision | None
    classification: Classification | None
    seen: bool  # the patient was found in this observation


def _priority(classification: Classification | None, decision: Decision | None) -> Priority:
    if decision == Decision.EMERGENCY:
        return Priority.KEPT
    if classification is not None and classification.raw_decision == Decision.EMERGENCY:
        return Priority.KEPT  # an Emergency waiting for the delay filter is kept too
    if decision == Decision.PAUSE:
        return Priority.PAUSE
    return Priority.NORMAL


def _finite_or_none(value: float) -> float | None:
    return float(value) if math.isfinite(value) else None


class Pipeline:
    def __init__(
        self,
        outbox: Outbox,
        mode: TransportMode,
        classifier: FrameClassifier | None = None,
        tracker: PatientTracker | None = None,
        depth_sampler: DepthSampler | None = None,
        ground_truth_fallback: bool = False,
        camera_mount: CameraMount | None = None,
    ) -> None:
        self.outbox = outbox
        self.mode = TransportMode(mode)
        self.classifier = classifier
        self.shadow: FrameClassifier | None = None  # a candidate: decisions stored, never alarmed
        self.tracker = tracker if tracker is not None else TrackingPatientTracker()
        self.depth_sampler = depth_sampler if depth_sampler is not None else sample_depth
        self.ground_truth_fallback = ground_truth_fallback
        self.camera_mount = camera_mount
        self._floor_warned = False
        self.transport_id: str | None = None
        self._transport_started = 0.0
        self._clock_offset: float | None = None  # wall time minus source time
        self._last_ts: float | None = None
        self._last_wall_ts = 0.0
        self._history: deque[SkeletonFrame] = deque(maxlen=WARMUP_FRAMES)
        self.last_decision: Decision | None = None

    @property
    def running_model(self) -> str | None:
        if self.classifier is not None:
            return self.classifier.manifest.version
        return GROUND_TRUTH_VERSION if self.ground_truth_fallback else None

    # --- transports ------------------------------------------------------------------------
    def start_transport(
        self, transport_id: str, ts: float, patient: str | None = None, location: str | None = None
    ) -> None:
        if self.transport_id is not None:
            self.end_transport(ts)
        self.transport_id = transport_id
        self._floor_warned = False
        self._transport_started = ts
        self._clock_offset = None
        self._last_ts = None
        self.tracker.reset()
        for model in (self.classifier, self.shadow):
            if model is not None:
                model.reset()
        self._history.clear()
        self.last_decision = None
        message = TransportStart(
            transport_id=transport_id, mode=self.mode, patient=patient, location=location, ts=ts
        )
        self.outbox.add_message(message.model_dump_json())

    def end_transport(self, ts: float) -> None:
        if self.transport_id is None:
            return
        self.outbox.add_message(
            TransportEnd(transport_id=self.transport_id, ts=ts).model_dump_json()
        )
        self.transport_id = None

    # --- models ----------------------------------------------------------------------------
    def swap_model(self, classifier: FrameClassifier) -> None:
        """Run `classifier` from the next frame on, warmed up on this transport's frames."""
        classifier.reset()
        for frame in self._history:
            classifier.classify(frame)
        previous = self.running_model
        self.classifier = classifier
        log.info(
            "model %s now classifies the frames (was %s; warmed up on %d frames)",
            classifier.manifest.version,
            previous,
            len(self._history),
        )

    def _restart_stream(self, timestamp: float) -> None:
        """The source's clock went back (a recording started again): the features and the
        delay filter start a new stream; frame times keep running forward."""
        log.warning(
            "transport %s: source time went back from %.3f s to %.3f s; classifying a new stream",
            self.transport_id, self._last_ts, timestamp,
        )  # fmt: skip
        self.tracker.reset()
        for model in (self.classifier, self.shadow):
            if model is not None:
                model.reset()
        self._history.clear()
        self._clock_offset = self._last_wall_ts + 0.001 - timestamp

    def set_shadow(self, classifier: FrameClassifier | None) -> None:
        """Run `classifier` beside the model from the next frame on (None: stop)."""
        if classifier is not None:
            classifier.reset()
            for frame in self._history:
                classifier.classify(frame)
            log.info("shadow model %s runs beside %s", classifier.manifest.version,
                     self.running_model)  # fmt: skip
        elif self.shadow is not None:
            log.info("shadow model %s stopped", self.shadow.manifest.version)
        self.shadow = classifier

    def _check_floor(self, frame: SkeletonFrame) -> None:
        """Say once per transport when the model needs floor measures the robot cannot give."""
        classifier = self.classifier
        if (
            self._floor_warned
            or classifier is None
            or classifier.manifest.feature_set not in NEEDS_FLOOR
            or not np.isnan(frame.floor).all()
        ):
            return
        self._floor_warned = True
        log.warning(
            "model %s uses floor measures but this frame has none (no camera_mount, no depth, "
            "or too few keypoints with depth): its decisions rest on the keypoints alone",
            classifier.manifest.version,
        )

    # --- frames ----------------------------------------------------------------------------
    def process(self, observation: Observation) -> FrameResult:
        if self._last_ts is not None and observation.timestamp < self._last_ts:
            self._restart_stream(observation.timestamp)
        self._last_ts = observation.timestamp
        patient = self.tracker.update(observation).patient
        if patient is None:
            frame = SkeletonFrame(empty_keypoints(), timestamp=observation.timestamp)
        else:
            depth = patient.depth
            if observation.depth_image is not None and self.depth_sampler is not None:
                depth = self.depth_sampler(
                    observation.depth_image, patient.keypoints, observation.depth_scale_mm
                )
            floor = patient.floor
            if self.camera_mount is not None and np.isnan(floor).all():
                floor = floor_measures(patient.keypoints, depth, self.camera_mount)
            frame = SkeletonFrame(patient.keypoints, depth, observation.timestamp, floor)
            self._check_floor(frame)
        self._history.append(frame)
        shadow = self.shadow.classify(frame) if self.shadow is not None else None
        classification = None
        if self.classifier is not None:
            classification = self.classifier.classify(frame)
            decision = classification.decision
        elif self.ground_truth_fallback and observation.truth is not None:
            decision = DEFAULT_TAXONOMY.decision(observation.truth, self.mode)
        else:
            decision = None
        if self._clock_offset is None:
            anchor = self._transport_started if self.transport_id is not None else time.time()
            self._clock_offset = anchor - observation.timestamp
        wall_ts = observation.timestamp + self._clock_offset
        self._last_wall_ts = wall_ts
        body = self._frame_body(frame, wall_ts, decision, classification, shadow)
        seq = self.outbox.add_frame(body, _priority(classification, decision))
        changed = decision is not None and decision != self.last_decision
        if changed and (decision != Decision.NORMAL or self.last_decision is not None):
            log.info("transport %s frame %d: %s", self.transport_id, seq, decision.value.upper())
        self.last_decision = decision
        return FrameResult(seq, decision, classification, patient is not None)

    def _frame_body(
        self,
        frame: SkeletonFrame,
        wall_ts: float,
        decision: Decision | None,
        classification: Classification | None,
        shadow: Classification | None = None,
    ) -> str:
        keypoints = np.nan_to_num(frame.keypoints, nan=0.0, posinf=0.0, neginf=0.0)
        depth = [_finite_or_none(d) for d in frame.depth.tolist()]
        floor = frame.floor.tolist()
        fields: dict = {
            "ts": wall_ts,
            "transport_id": self.transport_id,
            "keypoints": keypoints.tolist(),
            "depth": None if all(d is None for d in depth) else depth,
            "floor": None if np.isnan(frame.floor).all() else [_finite_or_none(v) for v in floor],
            "decision": None if decision is None else decision.value,
        }
        if classification is not None:
            fields["scores"] = {k.value: v for k, v in classification.scores.items()}
            fields["model_version"] = classification.model_version
            fields["threshold"] = classification.threshold
            fields["delay_ms"] = classification.delay_ms
        elif decision is not None:  # the generator's label: no model, no threshold, no delay
            fields["scores"] = {decision.value: 1.0}
            fields["model_version"] = GROUND_TRUTH_VERSION
        if shadow is not None:
            fields["shadow"] = {
                "decision": shadow.decision.value,
                "scores": {k.value: v for k, v in shadow.scores.items()},
                "model_version": shadow.model_version,
            }
        # Validate here, not at the backend: a frame the backend refused would block the outbox.
        FrameRecord.model_validate({"seq": 0, **fields})
        return json.dumps(fields, allow_nan=False, separators=(",", ":"))

"""One camera frame to one stored, classified frame: tracking, depth sampling, features,
inference, threshold and delay filter (all from vigil), then the outbox write."""

from __future__ import annotations

import logging
import math
import time
import uuid
from dataclasses import dataclass

import numpy as np

from robot_agent.depth import sample_depth
from robot_agent.models import ModelManager
from robot_agent.outbox import Outbox
from robot_agent.sources import Observation
from robot_agent.tracking import PatientTracker, TrackState, find_aruco_markers
from vigil.classes import Decision, TransportMode
from vigil.protocol import TransportEnd, TransportStart
from vigil.skeleton import SkeletonFrame

log = logging.getLogger("robot_agent.pipeline")
TRUTH_MODEL_VERSION = "generated-ground-truth"


@dataclass(frozen=True, slots=True)
class FrameResult:
    seq: int
    decision: Decision | None


def _record(frame: SkeletonFrame, ts: float, transport_id: str | None) -> dict:
    kp = np.round(frame.keypoints.astype(np.float64), 2)
    kp[:, 2] = np.round(frame.keypoints[:, 2].astype(np.float64), 3)
    depth = [None if not math.isfinite(v) else round(float(v), 3) for v in frame.depth]
    return {
        "ts": round(ts, 4),
        "transport_id": transport_id,
        "keypoints": kp.tolist(),
        "depth": depth if any(v is not None for v in depth) else None,
    }


class FramePipeline:
    def __init__(
        self,
        outbox: Outbox,
        models: ModelManager | None,
        mode: TransportMode = TransportMode.WALKING,
        use_ground_truth: bool = False,
        depth_mm_per_unit: float = 1.0,
        image_size: tuple[int, int] = (640, 480),
    ) -> None:
        if models is None and not use_ground_truth:
            raise ValueError("model_dir: a model is needed unless ground truth is streamed")
        self.outbox = outbox
        self.models = models
        self.mode = TransportMode(mode)
        self.use_ground_truth = use_ground_truth
        self.depth_mm_per_unit = depth_mm_per_unit
        self.tracker = PatientTracker(image_size=image_size)
        self.transport_id: str | None = None
        self._wall_offset = time.time()
        self.last_decision: Decision | None = None
        self.frames_without_patient = 0

    @property
    def emergency_holds(self) -> bool:
        return self.last_decision == Decision.EMERGENCY

    def start_transport(
        self,
        mode: TransportMode | None = None,
        patient: str | None = None,
        transport_id: str | None = None,
        ts: float | None = None,
    ) -> str:
        if self.transport_id is not None:
            self.end_transport()
        self.mode = TransportMode(mode or self.mode)
        self.transport_id = transport_id or uuid.uuid4().hex[:16]
        start = time.time() if ts is None else ts
        self.outbox.put_control(
            TransportStart(
                transport_id=self.transport_id, mode=self.mode, patient=patient, ts=start
            ).model_dump(mode="json")
        )
        self.tracker.reset()
        if self.models and self.models.classifier:
            self.models.classifier.reset()
        self.last_decision = None
        self._wall_offset = start
        log.info("transport %s started (%s)", self.transport_id, self.mode.value)
        return self.transport_id

    def end_transport(self, ts: float | None = None) -> None:
        if self.transport_id is None:
            return
        self.outbox.put_control(
            TransportEnd(
                transport_id=self.transport_id, ts=time.time() if ts is None else ts
            ).model_dump(mode="json")
        )
        log.info("transport %s ended", self.transport_id)
        self.transport_id = None

    def process(self, obs: Observation) -> FrameResult | None:
        """Returns None when the patient is not in view (nothing is stored for that frame)."""
        if self.models is not None and self.models.swap_if_ready() and self.models.classifier:
            self.models.classifier.reset()
        markers = None
        if obs.rgb is not None and self.tracker.state is TrackState.SEARCHING:
            markers = find_aruco_markers(obs.rgb)
        patient = self.tracker.update(obs.people, markers)
        if patient is None:
            self.frames_without_patient += 1
            return None
        if obs.depth_image is not None:
            patient = SkeletonFrame(
                patient.keypoints,
                sample_depth(obs.depth_image, patient.keypoints, self.depth_mm_per_unit),
                obs.timestamp,
            )
        elif patient.timestamp != obs.timestamp:
            patient = SkeletonFrame(patient.keypoints, patient.depth, obs.timestamp)
        record = _record(patient, self._wall_offset + obs.timestamp, self.transport_id)
        if self.use_ground_truth:
            decision = obs.truth
            record.update(decision=decision, model_version=TRUTH_MODEL_VERSION)
        else:
            assert self.models is not None and self.models.classifier is not None
            result = self.models.classifier.classify(patient)
            decision = result.decision
            record.update(
                decision=decision,
                scores={str(k): round(v, 4) for k, v in result.scores.items()},
                model_version=result.model_version,
                threshold=result.threshold,
                delay_ms=result.delay_ms,
            )
        if decision != self.last_decision and decision is not None:
            log.info("decision now %s", decision.value)
        self.last_decision = decision
        seq = self.outbox.put_frame(record, emergency=decision == Decision.EMERGENCY)
        return FrameResult(seq, decision)

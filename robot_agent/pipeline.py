"""One robot's frame path: the transport around vigil.detector (patient -> depth -> floor ->
classification, with the keypoints-only fallback) -> outbox.

Everything here runs between two camera frames on the agent's event loop; a model swap
(`swap_model`) is also called there, so it always happens between two frames. The new model's
feature history is warmed up with the frames of the current transport it missed. When detection
degrades or recovers (vigil.detector), a `detection_status` message goes into the outbox beside
the frames, so the nurse board shows it.
"""

from __future__ import annotations

import logging
import math
import time
from collections.abc import Callable
from dataclasses import dataclass

import numpy as np

from robot_agent.behaviour import Behaviour
from robot_agent.outbox import Outbox, Priority
from vigil.classes import Decision, TransportMode
from vigil.depth import sample_depth
from vigil.detector import DepthSampler, DetectionStatusChange, Detector, PatientFrames
from vigil.floor import CameraMount
from vigil.observation import Observation
from vigil.protocol import (
    DetectionStatus,
    FrameRecord,
    TransportEnd,
    TransportStart,
    frame_body_json,
)
from vigil.runtime import Classification, FrameClassifier
from vigil.skeleton import SkeletonFrame
from vigil.taxonomy import DEFAULT_TAXONOMY
from vigil.tracking import PatientTracker

log = logging.getLogger(__name__)

#: model_version of frames whose decision is the generator's ground truth, not a model's.
GROUND_TRUTH_VERSION = "generated-ground-truth"


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


@dataclass
class _TransportCounts:
    frames: int = 0
    with_person: int = 0
    with_patient: int = 0
    refused_implausible: int = 0  # frames without the patient where someone was refused
    first_ts: float | None = None
    last_ts: float | None = None
    # Keeping real time: when the first frame was done (monotonic clock), how far the latest
    # frame's completion was behind the source's own pace from there at worst, and the seconds
    # this frame path (everything after the source) took per frame.
    first_done: float | None = None
    behind_max_s: float = 0.0
    path_s_total: float = 0.0
    path_s_max: float = 0.0
    # The agent process's CPU time (every thread: the source's pose estimation too) from the
    # first frame's end to the latest one's: what keeping the pace costs, whatever the host's load.
    cpu_first: float | None = None
    cpu_last: float = 0.0

    def add(
        self,
        ts: float,
        people: int,
        seen: bool,
        started: float,
        done: float,
        cpu: float,
        refused_implausible: bool = False,
    ) -> None:
        self.frames += 1
        self.with_person += people > 0
        self.with_patient += seen
        self.refused_implausible += refused_implausible
        self.first_ts = ts if self.first_ts is None else self.first_ts
        self.last_ts = ts
        self.first_done = done if self.first_done is None else self.first_done
        behind = (done - self.first_done) - (ts - self.first_ts)
        self.behind_max_s = max(self.behind_max_s, behind)
        self.path_s_total += done - started
        self.path_s_max = max(self.path_s_max, done - started)
        self.cpu_first = cpu if self.cpu_first is None else self.cpu_first
        self.cpu_last = cpu

    def pace(self) -> str:
        """How the robot kept the source's pace (docs/robot_agent.md: a file source at --speed 1
        is read ahead of its pace, so "behind" is 0 while the robot keeps up)."""
        if not self.frames:
            return "no frames"
        return (
            f"at most {self.behind_max_s:.2f} s behind the source's pace, frame path "
            f"{1000 * self.path_s_total / self.frames:.1f} ms a frame on average "
            f"(max {1000 * self.path_s_max:.1f} ms) after the source, "
            f"{1000 * (self.cpu_last - self.cpu_first) / max(self.frames - 1, 1):.1f} ms of the "
            "process's CPU a frame"
        )

    @property
    def fps(self) -> float | None:
        if self.frames < 2 or self.last_ts is None or self.last_ts <= self.first_ts:
            return None
        return (self.frames - 1) / (self.last_ts - self.first_ts)


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
        fallback: FrameClassifier | None = None,
        available_inputs: list[str] | None = None,
        clock: Callable[[], float] = time.monotonic,
        cpu_clock: Callable[[], float] = time.process_time,
    ) -> None:
        self.outbox = outbox
        self._clock, self._cpu_clock = clock, cpu_clock
        self.mode = TransportMode(mode)
        frames = PatientFrames(
            tracker, depth_sampler if depth_sampler is not None else sample_depth, camera_mount
        )
        self.detector = Detector(classifier, frames, fallback, available_inputs)
        self.shadow: FrameClassifier | None = None  # a candidate: decisions stored, never alarmed
        self.ground_truth_fallback = ground_truth_fallback
        self.transport_id: str | None = None
        self._transport_started = 0.0
        self._clock_offset: float | None = None  # wall time minus source time
        self._last_ts: float | None = None
        self._last_wall_ts = 0.0
        self._counts = _TransportCounts()
        self.last_decision: Decision | None = None
        self.refused: str | None = None  # a model refused since the last verified one
        self.behaviour: Behaviour | None = None  # what the robot does with the decisions
        # Told every frame after its decision and behaviour (e.g. the rosbag recorder):
        # (observation, result, transport_id).
        self.frame_listeners: list[Callable[[Observation, FrameResult, str | None], None]] = []

    @property
    def classifier(self) -> FrameClassifier | None:
        """The assigned model."""
        return self.detector.classifier

    @property
    def fallback(self) -> FrameClassifier | None:
        return self.detector.fallback

    @property
    def running_model(self) -> str | None:
        """The assigned model's version (what the fleet compares with its target)."""
        if self.classifier is not None:
            return self.classifier.manifest.version
        return GROUND_TRUTH_VERSION if self.ground_truth_fallback else None

    @property
    def running_sha256(self) -> str | None:
        """sha256 of the file the assigned model was loaded from (what the fleet compares with
        the registry's sha256 of its target)."""
        return self.classifier.sha256 if self.classifier is not None else None

    def loaded_models(self) -> dict[str, str]:
        """What the hello tells about the model files this robot runs (protocol extension)."""
        out = {}
        if self.classifier is not None:
            out["running_sha256"] = self.classifier.sha256
        if self.fallback is not None:
            out["fallback_model"] = self.fallback.version
            out["fallback_sha256"] = self.fallback.sha256
        return out

    # --- transports ------------------------------------------------------------------------
    def start_transport(
        self,
        transport_id: str,
        ts: float,
        patient: str | None = None,
        location: str | None = None,
        fps: float | None = None,
    ) -> None:
        """fps: the source's real frame rate, told to the backend (None: not known)."""
        if self.transport_id is not None:
            self.end_transport(ts)
        self.transport_id = transport_id
        self._transport_started = ts
        self._clock_offset = None
        self._last_ts = None
        self._counts = _TransportCounts()
        self.detector.reset()
        if self.shadow is not None:
            self.shadow.reset()
        self.last_decision = None
        message = TransportStart(
            transport_id=transport_id,
            mode=self.mode,
            patient=patient,
            location=location,
            ts=ts,
            fps=fps,
        )
        self.outbox.add_message(message.model_dump_json(exclude_none=True))

    def end_transport(self, ts: float) -> None:
        if self.transport_id is None:
            return
        counts = self._counts
        fps = counts.fps
        log.info(
            "transport %s ended: %d frames, %d with a person in view, %d with the patient, "
            "%d refused as implausible (not a person: not dropped), %s; %s",
            self.transport_id,
            counts.frames,
            counts.with_person,
            counts.with_patient,
            counts.refused_implausible,
            "no frame rate" if fps is None else f"{fps:.1f} frames/s",
            counts.pace(),
        )
        self.outbox.add_message(
            TransportEnd(transport_id=self.transport_id, ts=ts).model_dump_json()
        )
        self.transport_id = None

    # --- models ----------------------------------------------------------------------------
    def swap_model(self, classifier: FrameClassifier) -> None:
        """Run `classifier` from the next frame on, warmed up on this transport's frames."""
        previous = self.running_model
        self.detector.set_model(classifier)
        log.info(
            "model %s now classifies the frames (was %s; warmed up on %d frames)",
            classifier.manifest.version,
            previous,
            len(self.detector.history),
        )
        if self.refused is not None:  # a verified model decides again: clear the refusal
            reason = (
                f"model {classifier.version}, verified against the registry's sha256, decides "
                f"again (model {self.refused} was refused)"
            )
            self.refused = None
            message = DetectionStatus(
                ts=time.time(),
                transport_id=self.transport_id,
                degraded=False,
                assigned_model=classifier.version,
                running_model=classifier.version,
                reason=reason[:500],
            )
            self.outbox.add_message(message.model_dump_json())

    def refuse_model(
        self, version: str, reason: str, replacement: FrameClassifier | None = None
    ) -> None:
        """The assigned model must not run (its file is not the registry's): from the next
        frame `replacement` (a verified keypoints-only fallback; None: nothing) decides, and the
        refusal goes to the nurse board as degraded detection."""
        self.detector.replace_model(replacement)
        self.report_refusal(version, reason)

    def report_refusal(self, version: str, reason: str) -> None:
        """Queue a detection_status (degraded, no input missing) saying model `version` was
        refused and what decides instead: a technical alarm on the nurse board, never lost."""
        self.refused = version
        running = self.running_model
        if self.classifier is not None:
            instead = f"deciding with {running}"
            if self.fallback is self.classifier:
                instead = f"deciding with the keypoints-only fallback {running}"
        elif running is not None:
            instead = f"decisions from {running}"
        else:
            instead = "no model decides until a verified one arrives"
        full = f"{reason}; {instead}"
        log.error("transport %s: %s", self.transport_id, full)
        message = DetectionStatus(
            ts=time.time(),
            transport_id=self.transport_id,
            degraded=True,
            missing_inputs=[],
            assigned_model=version[:64],
            running_model=running,
            reason=full[:500],
        )
        self.outbox.add_message(message.model_dump_json())

    def set_fallback(self, classifier: FrameClassifier | None) -> None:
        """Keep `classifier` (keypoints only) beside the assigned model (None: none)."""
        self.detector.set_fallback(classifier)
        if classifier is not None:
            log.info(
                "keypoints-only fallback %s kept beside %s",
                classifier.manifest.version,
                self.running_model,
            )

    def _restart_stream(self, timestamp: float) -> None:
        """The source's clock went back (a recording started again): the features and the
        delay filter start a new stream; frame times keep running forward."""
        log.warning(
            "transport %s: source time went back from %.3f s to %.3f s; classifying a new stream",
            self.transport_id,
            self._last_ts,
            timestamp,
        )
        self.detector.reset()
        if self.shadow is not None:
            self.shadow.reset()
        self._clock_offset = self._last_wall_ts + 0.001 - timestamp

    def set_shadow(self, classifier: FrameClassifier | None) -> None:
        """Run `classifier` beside the model from the next frame on (None: stop)."""
        if classifier is not None:
            classifier.reset()
            for frame in self.detector.history:
                classifier.classify(frame)
            log.info(
                "shadow model %s runs beside %s", classifier.manifest.version, self.running_model
            )
        elif self.shadow is not None:
            log.info("shadow model %s stopped", self.shadow.manifest.version)
        self.shadow = classifier

    def _report_status(self, change: DetectionStatusChange, wall_ts: float) -> None:
        (log.warning if change.degraded else log.info)(
            "transport %s: detection %s: %s",
            self.transport_id,
            "DEGRADED" if change.degraded else "recovered",
            change.reason,
        )
        message = DetectionStatus(
            ts=wall_ts,
            transport_id=self.transport_id,
            degraded=change.degraded,
            missing_inputs=list(change.missing_inputs),
            assigned_model=change.assigned_model,
            running_model=change.running_model,
            reason=change.reason[:500],
        )
        self.outbox.add_message(message.model_dump_json())

    # --- frames ----------------------------------------------------------------------------
    def process(self, observation: Observation) -> FrameResult:
        started = self._clock()
        if self._last_ts is not None and observation.timestamp < self._last_ts:
            self._restart_stream(observation.timestamp)
        self._last_ts = observation.timestamp
        detected = self.detector.process(observation)
        frame = detected.frame
        shadow = self.shadow.classify(frame) if self.shadow is not None else None
        classification = detected.classification
        if classification is not None:
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
        if detected.status is not None:
            self._report_status(detected.status, wall_ts)
        body = self._frame_body(frame, wall_ts, decision, classification, shadow)
        seq = self.outbox.add_frame(body, _priority(classification, decision))
        self._counts.add(
            observation.timestamp,
            detected.people,
            detected.seen,
            started,
            self._clock(),
            self._cpu_clock(),
            detected.refused_implausible,
        )
        changed = decision is not None and decision != self.last_decision
        if changed and (decision != Decision.NORMAL or self.last_decision is not None):
            log.info("transport %s frame %d: %s", self.transport_id, seq, decision.value.upper())
        self.last_decision = decision
        if self.behaviour is not None:
            self._behave(decision, wall_ts, detected.seen)
        result = FrameResult(seq, decision, classification, detected.seen)
        for listener in self.frame_listeners:
            listener(observation, result, self.transport_id)
        return result

    def _behave(self, decision: Decision | None, wall_ts: float, seen: bool) -> None:
        degraded = None
        if self.refused is not None:
            degraded = f"model {self.refused} failed its check"
        elif self.detector.degraded_:
            degraded = (
                "detection degraded: " + ", ".join(map(str, self.detector.missing_)) + " missing"
            )
        self.behaviour.update(
            decision, wall_ts, seen=seen, degraded=degraded, transport_id=self.transport_id
        )

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
        # seq 0 stands in: the body leaves it out and the outbox numbers the frame.
        return frame_body_json(FrameRecord.model_validate({"seq": 0, **fields}))

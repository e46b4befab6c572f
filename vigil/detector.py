"""The frame path every robot, benchmark and evaluation runs, in one place.

observation -> the patient (vigil.tracking) -> depth at the keypoints (vigil.depth) -> floor
measures (vigil.floor, with a camera mount) -> features -> ONNX model -> threshold and delay
(vigil.runtime). The robot agent's pipeline adds the transport, the shadow model and the outbox
around it; `make bench-detection` and the worker's gold-set evaluation replay recordings through
it (vigil.replay), so the figures they report are of this code.

Degraded detection. A model needs inputs (vigil.inputs): a floor model needs floor measures in
the frames. When the patient's frames lack one of them for ``degrade_after_s`` (or the robot
cannot feed it at all), the detector is *degraded*: it decides with its keypoints-only
``fallback`` model, which runs beside the assigned one on every frame so it is warm when needed,
and reports the change once (``DetectedFrame.status``) for the robot to raise "detection
degraded". When every input is back for ``recover_after_s`` the assigned model decides again and
the recovery is reported. Without a fallback the assigned model keeps deciding on what it has,
and the degradation is still reported.

Lost while falling. Beside the model, vigil.policy.LostWhileFalling watches the patient's hips:
when they were going down fast and the pose estimator then loses the patient, the decision is
Emergency at once (``Classification.rule`` says so), held while the patient stays lost,
whatever the model scores on the held pose; once they are seen again the model decides.
"""

from __future__ import annotations

from collections import deque
from collections.abc import Callable, Iterable
from dataclasses import dataclass, replace

import numpy as np

from vigil.classes import Decision
from vigil.depth import sample_depth
from vigil.features import FeatureExtractor
from vigil.floor import CameraMount, floor_measures
from vigil.inputs import (
    DEPTH,
    FLOOR,
    KEYPOINTS,
    InputName,
    describe_missing,
    is_keypoints_only,
    missing_inputs,
)
from vigil.observation import Observation
from vigil.policy import LOST_WHILE_FALLING, LostWhileFalling
from vigil.runtime import Classification, FrameClassifier
from vigil.skeleton import SkeletonFrame, empty_keypoints
from vigil.tracking import PatientTracker

DepthSampler = Callable[[np.ndarray, np.ndarray, float], np.ndarray]
"""(depth_image, keypoints (25, 3), depth_scale_mm) -> depth (25,) metres, NaN where unknown."""
HISTORY_FRAMES = 150  # frames of the current stream replayed into a newly swapped-in model
DEGRADE_AFTER_S = 0.5
RECOVER_AFTER_S = 1.0


def frame_inputs(frame: SkeletonFrame) -> frozenset[InputName]:
    """The inputs one patient frame carries."""
    have = {KEYPOINTS}
    if np.isfinite(frame.depth).any():
        have.add(DEPTH)
    if not np.isnan(frame.floor).all():
        have.add(FLOOR)
    return frozenset(have)


def _checked_fallback(fallback: FrameClassifier | None) -> FrameClassifier | None:
    if fallback is not None and not is_keypoints_only(fallback.manifest.inputs):
        raise ValueError(
            f"fallback model {fallback.manifest.version} needs {fallback.manifest.inputs}; "
            "a fallback must need keypoints only"
        )
    return fallback


class PatientFrames:
    """Observation -> the patient's frame: tracked, depth sampled, floor measures computed.

    A frame without the patient has no keypoints (and no depth or floor): the feature extractor
    holds the last pose for it, as in training. ``refused_`` is how many people in the last
    observation the tracker refused as implausible (vigil.tracking: not the patient)."""

    def __init__(
        self,
        tracker: PatientTracker | None = None,
        depth_sampler: DepthSampler | None = sample_depth,
        camera_mount: CameraMount | None = None,
    ) -> None:
        self.tracker = tracker if tracker is not None else PatientTracker()
        self.depth_sampler = depth_sampler
        self.camera_mount = camera_mount
        self.refused_ = 0

    def reset(self) -> None:
        self.tracker.reset()
        self.refused_ = 0

    def __call__(self, observation: Observation) -> tuple[SkeletonFrame, bool]:
        result = self.tracker.update(observation)
        self.refused_ = result.refused
        patient = result.patient
        if patient is None:
            return SkeletonFrame(empty_keypoints(), timestamp=observation.timestamp), False
        depth = patient.depth
        if observation.depth_image is not None and self.depth_sampler is not None:
            depth = self.depth_sampler(
                observation.depth_image, patient.keypoints, observation.depth_scale_mm
            )
        floor = patient.floor
        if self.camera_mount is not None and np.isnan(floor).all():
            floor = floor_measures(patient.keypoints, depth, self.camera_mount)
        return SkeletonFrame(patient.keypoints, depth, observation.timestamp, floor), True


def patient_stream(
    observations: Iterable[Observation], patient_frames: PatientFrames | None = None
) -> tuple[list[SkeletonFrame], np.ndarray]:
    """A recording's patient frames as the robot makes them, and which had the patient: what
    models are trained on, so that training sees what the robot classifies."""
    patient_frames = patient_frames if patient_frames is not None else PatientFrames()
    patient_frames.reset()
    frames, seen = [], []
    for observation in observations:
        frame, found = patient_frames(observation)
        frames.append(frame)
        seen.append(found)
    return frames, np.asarray(seen, bool)


def stream_features(
    observations: Iterable[Observation],
    feature_set: str = "full",
    patient_frames: PatientFrames | None = None,
) -> tuple[np.ndarray, np.ndarray]:
    """A recording's feature rows (n, d) exactly as the robot computes them, and which frames had
    the patient: each observation through the patient frames (tracker, vigil.depth, vigil.floor)
    and the streaming vigil.features.FeatureExtractor, frame by frame, as a FrameClassifier on the
    robot pushes them. The training rows (worker.training.data.build_rows) are made here."""
    patient_frames = patient_frames if patient_frames is not None else PatientFrames()
    patient_frames.reset()
    extractor = FeatureExtractor(feature_set)
    rows, seen = [], []
    for observation in observations:
        frame, found = patient_frames(observation)
        rows.append(extractor.push(frame))
        seen.append(found)
    features = np.stack(rows) if rows else np.zeros((0, extractor.n_features), np.float32)
    return features, np.asarray(seen, bool)


@dataclass(frozen=True, slots=True)
class DetectionStatusChange:
    """Detection degraded (or recovered) at ``ts``: what the robot reports to the backend."""

    ts: float
    degraded: bool
    missing_inputs: tuple[InputName, ...]
    assigned_model: str | None
    running_model: str | None
    reason: str


@dataclass(frozen=True, slots=True)
class DetectedFrame:
    frame: SkeletonFrame  # the patient's frame as classified
    seen: bool  # the patient was found in this observation
    people: int  # people in view
    classification: Classification | None  # of the model that decides (None: no model)
    status: DetectionStatusChange | None = None  # set on the frame detection degraded/recovered
    refused: int = 0  # people in view the tracker refused as implausible (furniture, not a body)

    @property
    def refused_implausible(self) -> bool:
        """Nobody passed on, and somebody in view was refused as implausible: not a dropped
        frame (a frame where a plausible person went unmatched)."""
        return not self.seen and self.refused > 0

    @property
    def dropped(self) -> bool:
        """A plausible person in view, but no patient passed on."""
        return not self.seen and self.people - self.refused > 0


class Detector:
    """One stream (one patient) through the frame path; reset() when a transport starts.

    classifier: the assigned model (None: nothing classifies). fallback: a keypoints-only model
    to decide with while the assigned one lacks an input. available_inputs: what the robot can
    feed (vigil.inputs; None: not declared, judged from the frames only)."""

    def __init__(
        self,
        classifier: FrameClassifier | None = None,
        patient_frames: PatientFrames | None = None,
        fallback: FrameClassifier | None = None,
        available_inputs: Iterable[str] | None = None,
        degrade_after_s: float = DEGRADE_AFTER_S,
        recover_after_s: float = RECOVER_AFTER_S,
    ) -> None:
        self.classifier = classifier
        self.fallback = _checked_fallback(fallback)
        self.patient_frames = patient_frames if patient_frames is not None else PatientFrames()
        self.available_inputs = None if available_inputs is None else frozenset(available_inputs)
        self.degrade_after_s = degrade_after_s
        self.recover_after_s = recover_after_s
        self.history: deque[SkeletonFrame] = deque(maxlen=HISTORY_FRAMES)
        self.lost_while_falling = LostWhileFalling()
        self.reset()

    # --- state ------------------------------------------------------------------------------
    def reset(self) -> None:
        self.patient_frames.reset()
        for model in (self.classifier, self.fallback):
            if model is not None:
                model.reset()
        self.history.clear()
        self.lost_while_falling.reset()
        self.degraded_ = False
        self.missing_: tuple[InputName, ...] = ()
        self._lacking_since: float | None = None
        self._complete_since: float | None = None
        # What the last report of this stream said (None: nothing reported yet).
        self._reported_degraded: bool | None = None

    @property
    def needed_inputs(self) -> tuple[InputName, ...]:
        return () if self.classifier is None else tuple(self.classifier.manifest.inputs)

    @property
    def deciding(self) -> FrameClassifier | None:
        """The model whose decisions count now."""
        if self.degraded_ and self.fallback is not None:
            return self.fallback
        return self.classifier

    @property
    def deciding_model(self) -> str | None:
        model = self.deciding
        return None if model is None else model.manifest.version

    def _warm(self, model: FrameClassifier) -> None:
        model.reset()
        for frame in self.history:
            model.classify(frame)

    def set_model(self, classifier: FrameClassifier) -> None:
        """Classify with ``classifier`` from the next frame on, warmed up on this stream."""
        self._warm(classifier)
        self.classifier = classifier
        self._judge_again()

    def replace_model(self, classifier: FrameClassifier | None) -> None:
        """A refused model stops deciding at once: ``classifier`` (a verified keypoints-only
        fallback, or None: nothing) decides from the next frame on. The caller reports why;
        degradation is judged afresh, with nothing reported yet for this model."""
        if classifier is not None:
            self._warm(classifier)
        self.classifier = classifier
        self._judge_again()
        self._reported_degraded = None

    def set_fallback(self, fallback: FrameClassifier | None) -> None:
        if _checked_fallback(fallback) is not None:
            self._warm(fallback)
        self.fallback = fallback
        if self.degraded_:
            self._reported_degraded = None  # the model deciding changed: say so again

    def _judge_again(self) -> None:
        """A new model: degradation is judged afresh for what it needs (a recovery is reported
        on the next frame if the new model has everything)."""
        self.degraded_, self.missing_ = False, ()
        self._lacking_since = self._complete_since = None

    # --- frames -----------------------------------------------------------------------------
    def process(self, observation: Observation) -> DetectedFrame:
        frame, seen = self.patient_frames(observation)
        self.history.append(frame)
        status = self._update_status(frame, seen) if self.classifier is not None else None
        primary = self.classifier.classify(frame) if self.classifier is not None else None
        backup = None
        if self.fallback is not None and not is_keypoints_only(self.needed_inputs):
            backup = self.fallback.classify(frame)
        classification = backup if (self.degraded_ and backup is not None) else primary
        fallen = self.lost_while_falling.update(frame, seen)
        if fallen and classification is not None and Decision.EMERGENCY in classification.scores:
            classification = replace(
                classification,
                decision=Decision.EMERGENCY,
                raw_decision=Decision.EMERGENCY,
                pending=False,
                rule=LOST_WHILE_FALLING,
            )
        return DetectedFrame(
            frame,
            seen,
            len(observation.people),
            classification,
            status,
            self.patient_frames.refused_,
        )

    def _update_status(self, frame: SkeletonFrame, seen: bool) -> DetectionStatusChange | None:
        needed = self.needed_inputs
        ts = frame.timestamp
        declared = missing_inputs(needed, self.available_inputs) if self.available_inputs else []
        if declared:  # the robot cannot feed it at all: degraded from the first frame
            missing = tuple(declared)
            self._lacking_since = ts if self._lacking_since is None else self._lacking_since
            lacking_for = float("inf")
        elif seen:  # only the patient's frames say what the robot feeds
            missing = tuple(missing_inputs(needed, frame_inputs(frame)))
            if missing:
                self._complete_since = None
                self._lacking_since = ts if self._lacking_since is None else self._lacking_since
            else:
                self._lacking_since = None
                self._complete_since = ts if self._complete_since is None else self._complete_since
            lacking_for = ts - self._lacking_since if missing else 0.0
        else:
            missing, lacking_for = self.missing_, 0.0
        if not self.degraded_ and missing and lacking_for >= self.degrade_after_s - 1e-6:
            self.degraded_, self.missing_ = True, missing
        elif (
            self.degraded_
            and not missing
            and self._complete_since is not None
            and ts - self._complete_since >= self.recover_after_s - 1e-6
        ):
            self.degraded_, self.missing_ = False, ()
        if self.degraded_ == bool(self._reported_degraded):
            return None  # nothing new: degraded and said so, or fine and never said otherwise
        return self._report(ts)

    def _report(self, ts: float) -> DetectionStatusChange:
        self._reported_degraded = self.degraded_
        assigned = self.classifier.manifest.version if self.classifier is not None else None
        if self.degraded_:
            reason = describe_missing(assigned or "-", self.missing_)
            if self.fallback is not None:
                reason += f"; deciding with the keypoints-only model {self.deciding_model}"
            else:
                reason += "; no keypoints-only fallback on this robot, the model decides on what "
                reason += "it has"
        else:
            reason = f"every input of model {assigned} is back; it decides again"
        return DetectionStatusChange(
            ts, self.degraded_, self.missing_, assigned, self.deciding_model, reason
        )

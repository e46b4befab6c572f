"""The model lane of the timeline: per-frame Emergency probability and suggested segments.

Stored scores (frames classified on a robot or in replay) are used when the video has them;
otherwise, when a model directory is configured, the frames are classified here with
vigil.runtime (results cached per video and model version).
"""

from __future__ import annotations

import logging
import threading
from dataclasses import dataclass
from pathlib import Path

import numpy as np
from sqlalchemy import select
from sqlalchemy.orm import Session

from backend.models.videos import Frame, Video
from backend.storage.frame_reads import of_video
from vigil.classes import Decision
from vigil.skeleton import (
    N_KEYPOINTS,
    SkeletonFrame,
    decode_depth,
    decode_floor,
    decode_keypoints,
)

log = logging.getLogger("vigil.labelling")

MIN_SUGGESTION_FRAMES = 5
SUGGESTED_LABEL = "falling"  # the annotator refines it into falling / impact / lying_on_floor


@dataclass(frozen=True, slots=True)
class Lane:
    source: str  # "stored", "model", "none"
    model_version: str | None
    threshold: float | None
    probability: list[float | None]  # per frame index, None where unknown
    suggestions: list[tuple[int, int]]
    error: str | None = None


def suggestions(probability: list[float | None], threshold: float) -> list[tuple[int, int]]:
    runs, start = [], None
    for i, p in enumerate([*probability, None]):
        above = p is not None and p >= threshold
        if above and start is None:
            start = i
        elif not above and start is not None:
            if i - start >= MIN_SUGGESTION_FRAMES:
                runs.append((start, i - 1))
            start = None
    return runs


class LaneComputer:
    """Classifies a whole video with the configured model; thread-safe, cached."""

    def __init__(self, model_dir: Path | None) -> None:
        self.model_dir = model_dir
        self._cache: dict[tuple[int, str], Lane] = {}
        self._lock = threading.Lock()
        self._classifier = None

    def available(self) -> bool:
        return self.model_dir is not None and (self.model_dir / "manifest.json").is_file()

    def lane(self, session: Session, video: Video) -> Lane:
        stored = _stored_lane(session, video)
        if stored is not None or not self.available():
            return stored or Lane("none", None, None, [None] * video.frame_count, [])
        with self._lock:
            try:
                if self._classifier is None:
                    from vigil.runtime import FrameClassifier  # onnxruntime only when needed

                    self._classifier = FrameClassifier.from_dir(self.model_dir)
                classifier = self._classifier
                key = (video.id, classifier.manifest.version)
                if key not in self._cache:
                    self._cache[key] = _computed_lane(session, video, classifier)
                return self._cache[key]
            except Exception as error:  # a broken or incompatible model must not break labelling
                log.warning("model lane for video %s failed: %s", video.id, error)
                return Lane(
                    "none",
                    None,
                    None,
                    [None] * video.frame_count,
                    [],
                    error=f"model in {self.model_dir} could not score this video: {error}",
                )


def _stored_lane(session: Session, video: Video) -> Lane | None:
    rows = session.execute(
        select(Frame.index, Frame.scores, Frame.model_version, Frame.threshold).where(
            *of_video(session, video), Frame.scores.is_not(None)
        )
    ).all()
    if not rows:
        return None
    probability: list[float | None] = [None] * video.frame_count
    for index, scores, _, _ in rows:
        value = (scores or {}).get(Decision.EMERGENCY.value)
        if value is not None and 0 <= index < video.frame_count:
            probability[index] = float(value)
    versions = {r[2] for r in rows if r[2]}
    thresholds = [r[3] for r in rows if r[3] is not None]
    threshold = float(np.median(thresholds)) if thresholds else 0.5
    return Lane(
        "stored",
        ", ".join(sorted(versions)) or None,
        threshold,
        probability,
        suggestions(probability, threshold),
    )


def _computed_lane(session: Session, video: Video, classifier) -> Lane:
    rows = session.execute(
        select(Frame.index, Frame.ts, Frame.keypoints, Frame.depth, Frame.floor)
        .where(*of_video(session, video))
        .order_by(Frame.index)
    ).all()
    classifier.reset()
    probability: list[float | None] = [None] * video.frame_count
    emergency = classifier.manifest.classes.index(Decision.EMERGENCY)
    no_depth = np.full(N_KEYPOINTS, np.nan, np.float32)
    for index, ts, blob, depth, floor in rows:
        depth = no_depth if depth is None else decode_depth(depth)
        frame = SkeletonFrame(decode_keypoints(blob), depth, ts, decode_floor(floor))
        scores = classifier.scores(frame)
        # ONNX sums tree votes in float32: 1.0000001 is a certain 1.
        probability[index] = min(max(float(scores[emergency]), 0.0), 1.0)
    threshold = float(classifier.manifest.threshold)
    return Lane(
        "model",
        classifier.manifest.version,
        threshold,
        probability,
        suggestions(probability, threshold),
    )

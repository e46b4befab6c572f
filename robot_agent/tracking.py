"""Patient selection and frame-to-frame tracking among several people in view.

At the start of a transport the patient is the person wearing the ArUco marker (when an RGB
image is available and a marker is found inside someone's torso), else the most central,
closest person. Afterwards the patient is followed by keypoint distance (with a constant
velocity prediction and, when known, depth), tolerating up to ``max_missed`` frames without a
match; everyone else is discarded.
"""

from __future__ import annotations

from dataclasses import dataclass
from enum import StrEnum

import numpy as np

from vigil.skeleton import INDEX, SkeletonFrame

TORSO = [INDEX[k] for k in ("neck", "r_shoulder", "l_shoulder", "mid_hip", "r_hip", "l_hip")]


class TrackState(StrEnum):
    SEARCHING = "searching"  # no patient chosen yet (start of transport or lost)
    TRACKING = "tracking"
    MISSING = "missing"  # patient not matched for a few frames; still the same identity


def _present(frame: SkeletonFrame) -> np.ndarray:
    return frame.keypoints[:, 2] > 0


def _centre(frame: SkeletonFrame) -> np.ndarray:
    return frame.keypoints[_present(frame), :2].mean(axis=0)


def _height(frame: SkeletonFrame) -> float:
    xy = frame.keypoints[_present(frame), :2]
    return float(np.ptp(xy[:, 1])) if len(xy) else 0.0


def _median_depth(frame: SkeletonFrame) -> float:
    depth = frame.depth[_present(frame)]
    depth = depth[np.isfinite(depth)]
    return float(np.median(depth)) if depth.size else float("nan")


def find_aruco_markers(rgb: np.ndarray, dictionary: int | None = None) -> list[np.ndarray]:
    """Centres (x, y) of ArUco markers in an RGB/BGR or grey image (OpenCV)."""
    import cv2

    dictionary = cv2.aruco.DICT_4X4_50 if dictionary is None else dictionary
    detector = cv2.aruco.ArucoDetector(
        cv2.aruco.getPredefinedDictionary(dictionary), cv2.aruco.DetectorParameters()
    )
    grey = rgb if rgb.ndim == 2 else cv2.cvtColor(rgb, cv2.COLOR_BGR2GRAY)
    corners, ids, _ = detector.detectMarkers(grey)
    if ids is None:
        return []
    return [c.reshape(4, 2).mean(axis=0) for c in corners]


def select_patient(
    people: list[SkeletonFrame],
    image_size: tuple[int, int] = (640, 480),
    markers: list[np.ndarray] | None = None,
) -> int | None:
    """Index of the patient among ``people``: the one whose torso holds a marker, else the
    most central, closest one."""
    if not people:
        return None
    for marker in markers or []:
        for i, person in enumerate(people):
            torso = person.keypoints[TORSO]
            torso = torso[torso[:, 2] > 0, :2]
            if len(torso) < 2:
                continue
            lo, hi = torso.min(0) - 15, torso.max(0) + 15
            if np.all(marker >= lo) and np.all(marker <= hi):
                return i
    width, height = image_size
    best, best_score = None, np.inf
    for i, person in enumerate(people):
        if not _present(person).any():
            continue
        off_centre = abs(_centre(person)[0] - width / 2) / (width / 2)  # 0 .. 1
        depth = _median_depth(person)
        # closeness: depth when known, else apparent size
        far = depth / 5.0 if np.isfinite(depth) else 1.0 - min(_height(person) / height, 1.0)
        score = off_centre + far
        if score < best_score:
            best, best_score = i, score
    return best


@dataclass
class PatientTracker:
    image_size: tuple[int, int] = (640, 480)
    max_missed: int = 60  # frames without a match before the patient counts as lost
    gate: float = 0.5  # max mean keypoint distance, as a share of the patient's height
    depth_weight_px_per_m: float = 400.0
    depth_slack_m_per_frame: float = 0.05  # how far the patient may move in depth per frame

    def __post_init__(self) -> None:
        self.state = TrackState.SEARCHING
        self.missed = 0
        self._last: SkeletonFrame | None = None
        self._velocity = np.zeros(2, np.float32)

    def reset(self) -> None:
        """A new transport: choose the patient again."""
        self.__post_init__()

    def _cost(self, person: SkeletonFrame, predicted: np.ndarray, gap: int) -> float:
        assert self._last is not None
        both = _present(person) & (self._last.keypoints[:, 2] > 0)
        if both.sum() >= 3:
            diff = person.keypoints[both, :2] - self._last.keypoints[both, :2] - predicted
            cost = float(np.linalg.norm(diff, axis=1).mean())
        else:
            cost = float(np.linalg.norm(_centre(person) - _centre(self._last) - predicted))
        dz = _median_depth(person) - _median_depth(self._last)
        if np.isfinite(dz):
            slack = min(self.depth_slack_m_per_frame * gap, 0.2)
            cost += self.depth_weight_px_per_m * max(abs(dz) - slack, 0.0)
        return cost

    def update(
        self, people: list[SkeletonFrame], markers: list[np.ndarray] | None = None
    ) -> SkeletonFrame | None:
        """The patient in this frame, or None when not seen."""
        if self.state is TrackState.SEARCHING:
            chosen = select_patient(people, self.image_size, markers)
            if chosen is None:
                return None
            self._accept(people[chosen])
            return people[chosen]
        assert self._last is not None
        gap = self.missed + 1
        predicted = self._velocity * gap
        gate = self.gate * max(_height(self._last), 60.0) * (1 + 0.05 * self.missed)
        costs = [self._cost(p, predicted, gap) for p in people]
        if costs and min(costs) <= gate:
            best = people[int(np.argmin(costs))]
            self._accept(best, gap)
            return best
        self.missed += 1
        self.state = TrackState.MISSING
        if self.missed > self.max_missed:
            self.reset()
        return None

    def _accept(self, person: SkeletonFrame, gap: int = 1) -> None:
        if self._last is not None and self.state is not TrackState.SEARCHING:
            both = _present(person) & (self._last.keypoints[:, 2] > 0)
            if both.sum() >= 3:  # displacement of shared keypoints: robust to occlusion
                step = np.median(person.keypoints[both, :2] - self._last.keypoints[both, :2], 0)
                self._velocity = 0.6 * self._velocity + 0.4 * step / gap
        self._last = person
        self.missed = 0
        self.state = TrackState.TRACKING

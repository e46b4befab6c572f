"""Which of the people in view is the patient, frame after frame.

At the start of a transport the tracker is SEARCHING: it picks the patient once, as

1. the person wearing an ArUco marker (``cv2.aruco`` DICT_4X4_50; the marker's centre must lie
   inside the person's torso box) when the observation has an RGB image, else
2. the most central, closest person: the lowest sum of the horizontal offset from the image
   centre (0 centre, 1 edge) and the relative distance (median keypoint depth when every
   candidate has depth, else inverse skeleton height; 0 for the closest, 1 for twice as far).

Then it is TRACKING. Everyone in view is followed internally (so a bystander walking in front
of the patient keeps their own identity): detections are matched to the followed people
greedily, lowest cost first, where the cost is the mean pixel distance over the joints both
skeletons have divided by the skeleton height, within a gate. Only the patient is reported;
everyone else is discarded. People seen in the same frame as the patient are marked bystanders.

A frame without the patient makes it LOST. It becomes TRACKING again when the patient's track
is matched (the gate widens a little per missed frame), or when a person who appeared since the
patient was lost, and is no known bystander, shows up near the patient's last position (the
patient changed pose while hidden). After ``max_missed`` frames it is SEARCHING and selects
anew, never choosing a known bystander (the marker, if seen, still decides).

Furniture is not the patient (issue #34). A detection whose geometry cannot be the patient is
*refused*: never matched to the patient, never selected, and counted per frame
(``TrackResult.refused``) apart from frames where a plausible person went unmatched. Two checks,
both in body sizes (ratios), never pixels, so they hold for any camera and pose estimator:

- proportions (``implausible_proportions``): with at least ``MIN_SEGMENTS`` of the torso, limb,
  shoulder and hip segments measured, the longest more than ``MAX_SEGMENT_RATIO`` times their
  median is no body (a person seen from any side, lying or folded stays within it on every frame
  of URFD). Missing keypoints are never held against a skeleton.
- reach (``PatientTracker.reach``): while a patient seen in at least ``ESTABLISHED_FRAMES``
  frames is LOST, a lone, nearly whole skeleton
  (``FULL_BODY_KEYPOINTS``) whose centre lies more than ``reach`` of the patient's body sizes
  from where their last nearly whole skeleton was is not them: a patient lost after a fall lies
  where they went down. This is the office chair that MoveNet (URFD) and MediaPipe (fall-01)
  report as the only person once the patient is down: its proportions are a seated person's,
  its place is not the patient's. A refused track stays refused while it is followed
  (furniture does not become a person), and selection never takes it.
"""

from __future__ import annotations

from dataclasses import dataclass, replace
from enum import StrEnum

import numpy as np

from vigil.depth import people_with_depth
from vigil.observation import Observation
from vigil.skeleton import INDEX, SkeletonFrame
from vigil.states import StateMachine

TORSO = np.array(
    [INDEX[k] for k in ("neck", "r_shoulder", "l_shoulder", "mid_hip", "r_hip", "l_hip")]
)
MIN_SHARED_JOINTS = 3
MIN_PERSON_KEYPOINTS = 4
SCALE_MEMORY = 0.97  # share of a track's remembered body size kept per frame

#: Segments whose lengths the proportion check compares: torso, upper and lower arms and legs,
#: shoulders and hips.
SEGMENTS = np.array(
    [
        (INDEX[a], INDEX[b])
        for a, b in (
            ("neck", "mid_hip"),
            ("r_shoulder", "r_elbow"),
            ("l_shoulder", "l_elbow"),
            ("r_elbow", "r_wrist"),
            ("l_elbow", "l_wrist"),
            ("r_hip", "r_knee"),
            ("l_hip", "l_knee"),
            ("r_knee", "r_ankle"),
            ("l_knee", "l_ankle"),
            ("r_shoulder", "l_shoulder"),
            ("r_hip", "l_hip"),
        )
    ]
)
MIN_SEGMENTS = 5  # fewer measured segments: too little to judge, the skeleton is taken
MAX_SEGMENT_RATIO = 12.0  # longest segment / median segment (URFD's real people: at most 9.5)
#: Body joints (nose, shoulders, elbows, wrists, hips, knees, ankles: 13) a skeleton needs to be
#: judged by the reach check; partial detections have unreliable centres and are left to the gates.
BODY_JOINTS = np.array(
    [
        INDEX[k]
        for k in (
            "nose",
            "r_shoulder",
            "l_shoulder",
            "r_elbow",
            "l_elbow",
            "r_wrist",
            "l_wrist",
            "r_hip",
            "l_hip",
            "r_knee",
            "l_knee",
            "r_ankle",
            "l_ankle",
        )
    ]
)
FULL_BODY_KEYPOINTS = 8
REACH = 1.0  # patient body sizes from their last nearly whole skeleton, while they are LOST
#: Frames the patient must have been seen in before the reach check trusts where they were (a
#: transport that starts on the chair must not refuse the patient walking in).
ESTABLISHED_FRAMES = 15


class TrackState(StrEnum):
    SEARCHING = "searching"  # no patient chosen (start of a transport, or lost for too long)
    TRACKING = "tracking"  # the patient was matched in this frame
    LOST = "lost"  # the patient was not matched; still remembered for max_missed frames


#: Every allowed state change, declared once; anything else is a bug (IllegalTransition).
TRACKER = StateMachine(
    TrackState,
    edges={
        TrackState.SEARCHING: {TrackState.SEARCHING, TrackState.TRACKING},
        TrackState.TRACKING: {TrackState.TRACKING, TrackState.LOST},
        TrackState.LOST: {TrackState.LOST, TrackState.TRACKING, TrackState.SEARCHING},
    },
    attribute="state_",
    initial=TrackState.SEARCHING,
    subject="tracker",
)


class SelectedBy(StrEnum):
    MARKER = "aruco_marker"
    CENTRAL_CLOSEST = "central_closest"


@dataclass(frozen=True, slots=True)
class TrackResult:
    """The tracker's verdict for one observation.

    patient: the patient's skeleton in this frame (None unless state is TRACKING; with depth
    sampled when the observation had a depth image and the tracker samples depth);
    index: its position in ``observation.people``; selected_by: set on the frame the patient
    was chosen; missed: consecutive frames without a match.
    """

    state: TrackState
    patient: SkeletonFrame | None
    index: int | None
    selected_by: SelectedBy | None = None
    missed: int = 0
    refused: int = 0  # detections refused as implausible in this frame (not the patient)


def _box(keypoints: np.ndarray, joints: np.ndarray | None = None) -> np.ndarray | None:
    pts = keypoints if joints is None else keypoints[joints]
    pts = pts[pts[:, 2] > 0, :2]
    if len(pts) < 2:
        return None
    return np.concatenate([pts.min(0), pts.max(0)])


def skeleton_height(keypoints: np.ndarray) -> float:
    box = _box(keypoints)
    if box is None:
        return 0.0
    return float(max(box[3] - box[1], box[2] - box[0], 1.0))


def detect_markers(rgb: np.ndarray, dictionary: int | None = None) -> dict[int, np.ndarray]:
    """ArUco marker id -> centre (x, y) in pixels of the image (OpenCV's DICT_4X4_50 unless
    ``dictionary`` says otherwise). OpenCV is imported here: only sources with RGB need it."""
    import cv2

    if dictionary is None:
        dictionary = cv2.aruco.DICT_4X4_50
    grey = cv2.cvtColor(rgb, cv2.COLOR_BGR2GRAY) if rgb.ndim == 3 else rgb
    detector = cv2.aruco.ArucoDetector(cv2.aruco.getPredefinedDictionary(dictionary))
    corners, ids, _ = detector.detectMarkers(grey)
    if ids is None:
        return {}
    return {int(i): c.reshape(4, 2).mean(0) for i, c in zip(ids.ravel(), corners, strict=True)}


def marker_wearer(
    people: list[SkeletonFrame],
    markers: dict[int, np.ndarray],
    marker_id: int | None = None,
    margin: float = 0.15,
) -> int | None:
    """Index of the person whose torso box (widened by ``margin`` of its size) holds the marker
    (``marker_id``, or any marker when None); the smallest such box wins."""
    centres = [c for i, c in markers.items() if marker_id is None or i == marker_id]
    best, best_area = None, np.inf
    for index, person in enumerate(people):
        box = _box(person.keypoints, TORSO)
        if box is None:
            continue
        pad = margin * np.maximum(box[2:] - box[:2], 10.0)
        lo, hi = box[:2] - pad, box[2:] + pad
        area = float(np.prod(hi - lo))
        if any(np.all((c >= lo) & (c <= hi)) for c in centres) and area < best_area:
            best, best_area = index, area
    return best


def implausible_proportions(keypoints: np.ndarray) -> bool:
    """The skeleton's segment lengths cannot be a body's: with at least MIN_SEGMENTS of SEGMENTS
    measured, the longest is more than MAX_SEGMENT_RATIO times their median (scale-free)."""
    present = (keypoints[SEGMENTS[:, 0], 2] > 0) & (keypoints[SEGMENTS[:, 1], 2] > 0)
    if present.sum() < MIN_SEGMENTS:
        return False
    ends = keypoints[SEGMENTS[present]][:, :, :2]
    lengths = np.linalg.norm(ends[:, 0] - ends[:, 1], axis=1)
    median = float(np.median(lengths))
    return bool(lengths.max() > MAX_SEGMENT_RATIO * max(median, 1e-6))


def body_keypoints(keypoints: np.ndarray) -> int:
    """How many of the 13 BODY_JOINTS the skeleton has."""
    return int((keypoints[BODY_JOINTS, 2] > 0).sum())


def central_closest(people: list[SkeletonFrame], image_width: float) -> int | None:
    """Index of the most central, closest person (see the module docstring), None if nobody
    has a keypoint. People with at least MIN_PERSON_KEYPOINTS keypoints are preferred: a pose
    estimator's stray one- or two-joint detection is chosen only when nobody better is there."""
    counts = [int(p.present.sum()) for p in people]
    candidates = [i for i, n in enumerate(counts) if n >= MIN_PERSON_KEYPOINTS]
    if not candidates:
        candidates = [i for i, n in enumerate(counts) if n > 0]
    if not candidates:
        return None
    offsets, distances = [], []
    depths = [np.nanmedian(p.depth) if np.isfinite(p.depth).any() else np.nan for p in people]
    use_depth = all(np.isfinite(depths[i]) for i in candidates)
    for i in candidates:
        kp = people[i].keypoints
        centre_x = float(np.mean(kp[kp[:, 2] > 0, 0]))
        offsets.append(abs(centre_x - image_width / 2) / (image_width / 2))
        distances.append(depths[i] if use_depth else 1.0 / max(skeleton_height(kp), 1.0))
    distances_arr = np.asarray(distances)
    score = np.asarray(offsets) + distances_arr / distances_arr.min() - 1.0
    return candidates[int(np.argmin(score))]


def person_depth(person: SkeletonFrame) -> float:
    """Median keypoint depth in metres, NaN when unknown."""
    known = person.depth[np.isfinite(person.depth)]
    return float(np.median(known)) if known.size else float("nan")


def match_cost(predicted: np.ndarray, candidate: np.ndarray, scale: float) -> float:
    """Mean distance over the joints both skeletons have, in units of ``scale`` pixels
    (inf with fewer than MIN_SHARED_JOINTS shared joints)."""
    shared = (predicted[:, 2] > 0) & (candidate[:, 2] > 0)
    if shared.sum() < MIN_SHARED_JOINTS:
        return float("inf")
    gaps = np.linalg.norm(predicted[shared, :2] - candidate[shared, :2], axis=1)
    return float(gaps.mean() / scale)


def _gap_to_box(point: np.ndarray, box: np.ndarray) -> float:
    """Pixels from ``point`` to the nearest point of ``box`` (0 inside)."""
    return float(np.linalg.norm(np.maximum(np.maximum(box[:2] - point, point - box[2:]), 0.0)))


def body_gap(predicted: np.ndarray, candidate: np.ndarray, scale: float) -> float:
    """How far apart two skeletons' bodies are, whatever their poses, in units of ``scale``:
    the smaller of the gaps from each one's centre to the other's box (0 when a centre lies
    inside the other box). A person falling changes every joint's place within a few frames,
    and the pose estimator may see only a part of them, but the body stays where it was."""
    a, b = _box(predicted), _box(candidate)
    if a is None or b is None:
        pa, pb = predicted[predicted[:, 2] > 0, :2], candidate[candidate[:, 2] > 0, :2]
        if not len(pa) or not len(pb):
            return float("inf")
        return float(np.linalg.norm(pa.mean(0) - pb.mean(0)) / scale)
    centre_a, centre_b = (a[:2] + a[2:]) / 2, (b[:2] + b[2:]) / 2
    return min(_gap_to_box(centre_a, b), _gap_to_box(centre_b, a)) / scale


class _Track:
    """One person followed from frame to frame (the patient or someone to tell apart)."""

    __slots__ = (
        "keypoints",
        "depth",
        "velocity",
        "scale",
        "missed",
        "born",
        "bystander",
        "implausible",
        "whole",
        "matched",
    )

    def __init__(self, person: SkeletonFrame, born: int, min_scale: float) -> None:
        self.keypoints = person.keypoints.copy()
        self.depth = person_depth(person)
        self.velocity = np.zeros(2, np.float32)  # px per frame of the skeleton's centre
        self.scale = max(skeleton_height(self.keypoints), min_scale)
        self.missed = 0
        self.born = born  # frame count when first seen
        self.bystander = False  # seen in the same frame as the patient: not the patient
        self.implausible = False  # refused by the reach check: never the patient
        self.matched = 1  # frames this person was seen in
        self.whole: tuple[np.ndarray, float] | None = None  # last nearly whole body: centre, size
        self._remember_whole(person.keypoints)

    def _remember_whole(self, keypoints: np.ndarray) -> None:
        if body_keypoints(keypoints) >= FULL_BODY_KEYPOINTS:
            present = keypoints[:, 2] > 0
            self.whole = (keypoints[present, :2].mean(0), self.scale)

    def predicted(self) -> np.ndarray:
        out = self.keypoints.copy()
        out[:, :2] += self.velocity * (self.missed + 1)
        return out

    def centre(self) -> np.ndarray:
        present = self.keypoints[:, 2] > 0
        if not present.any():
            return np.full(2, np.inf, np.float32)
        return self.keypoints[present, :2].mean(0)

    def depth_differs(self, person: SkeletonFrame, limit: float) -> bool:
        """Both distances known and further apart than ``limit`` metres."""
        return bool(abs(person_depth(person) - self.depth) > limit)  # NaN compares False

    def accept(self, person: SkeletonFrame, min_scale: float) -> None:
        keypoints = person.keypoints
        depth = person_depth(person)
        if np.isfinite(depth):
            self.depth = depth
        frames = self.missed + 1
        present = keypoints[:, 2] > 0
        shared = present & (self.keypoints[:, 2] > 0)
        if shared.any():
            step = (keypoints[shared, :2] - self.keypoints[shared, :2]).mean(0) / frames
            self.velocity = (0.5 * self.velocity + 0.5 * step).astype(np.float32)
        merged = keypoints.copy()  # joints that went missing are kept, so matching has more
        merged[~present] = self.keypoints[~present]
        merged[~present, :2] += self.velocity * frames
        self.keypoints = merged
        # A partial detection (a few joints) must not shrink the gates to nothing: the size of
        # the body is remembered and forgets slowly (SCALE_MEMORY per frame).
        self.scale = max(skeleton_height(keypoints), SCALE_MEMORY**frames * self.scale, min_scale)
        self.missed = 0
        self.matched += 1
        self._remember_whole(keypoints)


class PatientTracker:
    """Selects the patient at the start of a transport and follows them (see module docstring).

    max_missed: frames the patient may go unmatched before the tracker searches anew (30: one
    second at 30 frames/s). gate: largest accepted match cost (mean joint distance / skeleton
    height) on the frame after a match; gate_growth is added per missed frame. body_gate: the
    largest body gap (``body_gap``, in skeleton heights) of the second, pose-free match for
    people the joints did not match (a fall, a partial detection); grows like the gate.
    reacquire_radius: how near (in skeleton heights) to the patient's last position a newly
    appeared person must be to be taken for the patient while LOST when others are in view too
    (a lone person who is no known bystander is taken wherever they are). depth_gate_m: when
    both a followed person and a detection have a known distance (median keypoint depth), they
    never match if it differs by more than this (scaled up per missed frame like the gate);
    sample depth for everyone before tracking to use it. marker_id: the ArUco id the patient
    wears (None: any DICT_4X4_50 marker). require_marker: with RGB, wait for a marker instead of
    falling back to the central, closest person. image_width: used when the observation
    carries no image. min_scale: the smallest body size used for the gates, as a share of the
    image width. sample_depth: when the observation has a depth image, sample everyone's depth
    first (one vectorised call, about 0.2 ms for five people) so distance separates people who
    overlap in the image; the reported patient then carries that depth. reach: how far (in the
    patient's body sizes) from their last nearly whole skeleton a lone, nearly whole skeleton may
    be while the patient is LOST and still be taken for them (module docstring).
    """

    def __init__(
        self,
        max_missed: int = 30,
        gate: float = 0.25,
        gate_growth: float = 0.02,
        body_gate: float = 0.5,
        reacquire_radius: float = 0.75,
        depth_gate_m: float = 0.6,
        marker_id: int | None = None,
        require_marker: bool = False,
        image_width: float = 640.0,
        min_scale: float = 0.1,
        sample_depth: bool = True,
        reach: float = REACH,
    ) -> None:
        if max_missed < 0:
            raise ValueError(f"max_missed must be >= 0, got {max_missed}")
        if gate <= 0:
            raise ValueError(f"gate must be positive, got {gate}")
        if body_gate < 0:
            raise ValueError(f"body_gate must be >= 0, got {body_gate}")
        self.max_missed = max_missed
        self.gate = gate
        self.gate_growth = gate_growth
        self.body_gate = body_gate
        self.reacquire_radius = reacquire_radius
        self.depth_gate_m = depth_gate_m
        self.marker_id = marker_id
        self.require_marker = require_marker
        self.image_width = image_width
        self.min_scale = min_scale
        self.sample_depth = sample_depth
        self.reach = reach
        self.reset()

    def reset(self) -> None:
        """Start over (a new transport): the next observation selects the patient anew."""
        TRACKER.start(self)
        self.tracks_: list[_Track] = []
        self.patient_: _Track | None = None
        self.frame_ = 0
        self.min_scale_px_ = self.min_scale * self.image_width

    @property
    def missed_(self) -> int:
        return self.patient_.missed if self.patient_ is not None else 0

    def update(self, observation: Observation) -> TrackResult:
        self.frame_ += 1
        self.min_scale_px_ = self.min_scale * self._width(observation)
        if self.sample_depth and observation.depth_image is not None and observation.people:
            observation = replace(observation, people=people_with_depth(observation))
        # Skeletons no body can make are not followed at all (implausible_proportions).
        kept = [
            i for i, p in enumerate(observation.people) if not implausible_proportions(p.keypoints)
        ]
        broken = len(observation.people) - len(kept)
        if broken:
            observation = replace(observation, people=[observation.people[i] for i in kept])
        result, assigned = self._update(observation)
        refused = broken + sum(
            track.implausible for i, track in assigned.items() if i != result.index
        )
        index = None if result.index is None else kept[result.index]
        return replace(result, index=index, refused=refused)

    def _update(self, observation: Observation) -> tuple[TrackResult, dict[int, _Track]]:
        people = observation.people
        assigned = self._associate(people)  # detection index -> track, for everyone
        if self.state_ is TrackState.SEARCHING:
            return self._select(observation, assigned), assigned
        index = next((i for i, t in assigned.items() if t is self.patient_), None)
        if index is None:
            index = self._reacquire(assigned)
        if index is not None:
            self._mark_bystanders(assigned)
            TRACKER.move(self, TrackState.TRACKING)
            return TrackResult(self.state_, people[index], index), assigned
        TRACKER.move(self, TrackState.LOST)
        if self.missed_ <= self.max_missed:
            return TrackResult(self.state_, None, None, missed=self.missed_), assigned
        TRACKER.move(self, TrackState.SEARCHING)
        self.patient_ = None
        return self._select(observation, assigned), assigned

    def _select(self, observation: Observation, assigned: dict[int, _Track]) -> TrackResult:
        people = observation.people
        index, how = None, None
        if observation.rgb is not None:
            index = marker_wearer(people, detect_markers(observation.rgb), self.marker_id)
            how = SelectedBy.MARKER
        if index is None and not (self.require_marker and observation.rgb is not None):
            candidates = [
                i
                for i in range(len(people))
                if not (assigned[i].bystander or assigned[i].implausible)
            ]
            choice = central_closest([people[i] for i in candidates], self._width(observation))
            index = None if choice is None else candidates[choice]
            how = SelectedBy.CENTRAL_CLOSEST
        if index is None:
            TRACKER.move(self, TrackState.SEARCHING)
            return TrackResult(self.state_, None, None)
        self.patient_ = assigned[index]
        self.patient_.bystander = False
        self._mark_bystanders(assigned)
        TRACKER.move(self, TrackState.TRACKING)
        return TrackResult(self.state_, people[index], index, selected_by=how)

    def _reacquire(self, assigned: dict[int, _Track]) -> int | None:
        """The patient was not matched: take a person who is no known bystander for them.

        When that person is the only one in view, they are (a fall can change a body beyond
        both gates within a frame; a partial detection can hide everything the gates compare).
        With others in view, only a person who appeared since the patient was lost and is near
        their last position is taken: a stranger stepping out from behind a bystander is not."""
        patient = self.patient_
        lost_at = self.frame_ - patient.missed
        last = patient.centre()
        depth_limit = self.depth_gate_m * (1 + 0.05 * patient.missed)
        candidates = [
            (index, track)
            for index, track in assigned.items()
            if not track.bystander
            and not track.implausible
            and not track.missed
            and not (np.isfinite(track.depth) and abs(track.depth - patient.depth) > depth_limit)
        ]
        best = None
        if len(candidates) == 1 and len(assigned) == 1:
            best = candidates[0][0]
            if self._out_of_reach(candidates[0][1]):
                candidates[0][1].implausible = True
                best = None
        else:
            best_distance = self.reacquire_radius
            for index, track in candidates:
                if track.born < lost_at:
                    continue
                distance = float(np.linalg.norm(track.centre() - last)) / patient.scale
                if distance <= best_distance:
                    best, best_distance = index, distance
        if best is not None:
            self.tracks_.remove(patient)
            self.patient_ = assigned[best]
        return best

    def _out_of_reach(self, track: _Track) -> bool:
        """A nearly whole skeleton farther than ``reach`` of the lost patient's body sizes from
        their last nearly whole skeleton (module docstring)."""
        whole = self.patient_.whole
        if (
            whole is None
            or self.patient_.matched < ESTABLISHED_FRAMES
            or body_keypoints(track.keypoints) < FULL_BODY_KEYPOINTS
        ):
            return False
        centre, size = whole
        return bool(np.linalg.norm(track.centre() - centre) > self.reach * size)

    def _mark_bystanders(self, assigned: dict[int, _Track]) -> None:
        for track in assigned.values():
            if track is not self.patient_:
                track.bystander = True

    def _width(self, observation: Observation) -> float:
        for image in (observation.rgb, observation.depth_image):
            if image is not None:
                return float(image.shape[1])
        return self.image_width

    def _pairs(
        self,
        people: list[SkeletonFrame],
        tracks: list[int],
        detections: list[int],
        cost,
        gate: float,
    ) -> list[tuple[float, int, int]]:
        pairs = []
        for t in tracks:
            track = self.tracks_[t]
            predicted = track.predicted()
            limit = gate + self.gate_growth * track.missed
            depth_limit = self.depth_gate_m * (1 + 0.05 * track.missed)
            for d in detections:
                if track.depth_differs(people[d], depth_limit):
                    continue
                value = cost(predicted, people[d].keypoints, track.scale)
                if value <= limit:
                    pairs.append((value, t, d))
        return sorted(pairs)

    def _associate(self, people: list[SkeletonFrame]) -> dict[int, _Track]:
        """Match detections to followed people (greedy, lowest cost first, within the gate: by
        joints first, then the people left by where their bodies are); unmatched detections
        start new tracks, tracks unmatched too long are dropped."""
        assigned: dict[int, _Track] = {}
        used: set[int] = set()
        for cost, gate in ((match_cost, self.gate), (body_gap, self.body_gate)):
            free_tracks = [t for t in range(len(self.tracks_)) if t not in used]
            free_people = [d for d in range(len(people)) if d not in assigned]
            for _, t, d in self._pairs(people, free_tracks, free_people, cost, gate):
                if t in used or d in assigned:
                    continue
                used.add(t)
                assigned[d] = self.tracks_[t]
                self.tracks_[t].accept(people[d], self.min_scale_px_)
        for t, track in enumerate(self.tracks_):
            if t not in used:
                track.missed += 1
        self.tracks_ = [
            t for t in self.tracks_ if t.missed <= self.max_missed or t is self.patient_
        ]
        for d, person in enumerate(people):
            if d not in assigned:
                track = _Track(person, born=self.frame_, min_scale=self.min_scale_px_)
                self.tracks_.append(track)
                assigned[d] = track
        return assigned

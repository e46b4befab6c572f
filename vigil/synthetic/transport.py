"""Transport assembly: a patient's script, bystanders and the camera put together into one
GENERATED transport, and the patient alone as arrays."""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np

from vigil.classes import MODE_CLASSES, Decision, TransportMode
from vigil.floor import floor_measures_many
from vigil.skeleton import INDEX, N_FLOOR, N_KEYPOINTS, SkeletonFrame
from vigil.synthetic.bystanders import bystander_params
from vigil.synthetic.camera import (
    CAMERA_MOUNT,
    FOCAL_PX,
    FPS,
    IMAGE_HEIGHT,
    IMAGE_WIDTH,
    MARKER_SIZE_M,
    MIN_VISIBLE_KEYPOINTS,
    CameraNoise,
    occlude,
    project,
    render,
)
from vigil.synthetic.kinematics import PARAMS, SIT_WHEELCHAIR, P, body_points, pose
from vigil.synthetic.scripts import (
    EMERGENCY_EVENTS,
    EVENTS,
    EVENTS_BY_LOCOMOTION,
    Builder,
    Locomotion,
    base_activity,
    upright,
)
from vigil.taxonomy import DEFAULT_TAXONOMY, Taxonomy


@dataclass(frozen=True)
class GeneratedSequence:
    """One GENERATED patient's frames as arrays."""

    name: str
    keypoints: np.ndarray  # (n, 25, 3) pixels of a 640x480 image
    depth: np.ndarray  # (n, 25) metres, NaN where unknown
    timestamps: np.ndarray  # (n,)
    fine_labels: tuple[str, ...]
    generated: bool = True
    floor: np.ndarray | None = None  # (n, 3) floor measures (vigil.floor), NaN where unknown


def class_targets(
    sequence: GeneratedSequence, mode: TransportMode | str, taxonomy: Taxonomy = DEFAULT_TAXONOMY
) -> np.ndarray:
    """Class index (in MODE_CLASSES[mode] order) of every frame."""
    mode = TransportMode(mode)
    classes = MODE_CLASSES[mode]
    return np.array([classes.index(taxonomy.decision(k, mode)) for k in sequence.fine_labels])


@dataclass
class GeneratedTransport:
    """A GENERATED transport.

    frames_per_person[p][t]: person p at frame t as a SkeletonFrame (BODY_25 pixels in a
    640x480 image, depth in metres), or None when the pose estimator would not see them.
    labels[t]: the patient's fine label at frame t. marker_px[t]: (u, v, side) in pixels of the
    ArUco marker on the patient's chest (NaN when not visible).
    """

    locomotion: Locomotion
    seed: int
    fps: float
    frames_per_person: list[list[SkeletonFrame | None]]
    patient_index: int
    labels: list[str]
    events: tuple[str, ...]
    marker_px: np.ndarray
    taxonomy: Taxonomy = DEFAULT_TAXONOMY
    generated: bool = True
    image_size: tuple[int, int] = (IMAGE_WIDTH, IMAGE_HEIGHT)

    @property
    def transport_mode(self) -> TransportMode:
        return self.locomotion.transport_mode

    @property
    def n_frames(self) -> int:
        return len(self.labels)

    @property
    def n_people(self) -> int:
        return len(self.frames_per_person)

    @property
    def duration_s(self) -> float:
        return self.n_frames / self.fps

    @property
    def patient_frames(self) -> list[SkeletonFrame | None]:
        return self.frames_per_person[self.patient_index]

    def decisions(self, mode: TransportMode | None = None) -> list[Decision]:
        """Ground-truth class per frame (for ``mode``, default the transport's own)."""
        mode = mode or self.transport_mode
        cache = {key: self.taxonomy.decision(key, mode) for key in set(self.labels)}
        return [cache[key] for key in self.labels]

    def detections(self, t: int) -> list[SkeletonFrame]:
        """What a pose estimator reports at frame t: everyone visible, in no particular order
        (a deterministic shuffle), without identities."""
        return [self.frames_per_person[i][t] for i in self.detection_ids(t)]  # type: ignore[misc]

    def detection_ids(self, t: int) -> list[int]:
        """Ground truth for ``detections(t)``: the person index of each detection, same order."""
        seen = [i for i, p in enumerate(self.frames_per_person) if p[t] is not None]
        order = np.random.default_rng((self.seed, t)).permutation(len(seen))
        return [seen[i] for i in order]

    def patient_sequence(self, name: str | None = None) -> GeneratedSequence:
        """The patient alone as a ``GeneratedSequence``: frames where the patient is not
        seen have every keypoint missing (confidence 0) and NaN depth."""
        n = self.n_frames
        keypoints = np.zeros((n, N_KEYPOINTS, 3), np.float32)
        depth = np.full((n, N_KEYPOINTS), np.nan, np.float32)
        floor = np.full((n, N_FLOOR), np.nan, np.float32)
        for t, frame in enumerate(self.patient_frames):
            if frame is not None:
                keypoints[t], depth[t], floor[t] = frame.keypoints, frame.depth, frame.floor
        return GeneratedSequence(
            name or f"gen-{self.locomotion.value}-seed{self.seed}",
            keypoints,
            depth,
            np.arange(n) / self.fps,
            tuple(self.labels),
            floor=floor,
        )


def generate_transport(
    mode: Locomotion | str = Locomotion.WALKING,
    seed: int = 0,
    duration_s: float = 30.0,
    events: Sequence[str] | None = None,
    n_people: int = 1,
    noise: CameraNoise | None = None,
) -> GeneratedTransport:
    """Generate one transport (GENERATED data).

    mode: walking, rollator or wheelchair. events: names from ``EVENTS_BY_LOCOMOTION[mode]``
    in order (None: one to three picked by the seed, at least one an emergency). n_people: 1-5
    people in view, the patient plus crossing bystanders. The transport lasts at least
    ``duration_s`` (longer when the events need it), normal activity filling the gaps.
    """
    locomotion = Locomotion(mode)
    if not 1 <= n_people <= 5:
        raise ValueError(f"n_people must be 1-5, got {n_people}")
    if duration_s <= 0:
        raise ValueError(f"duration_s must be positive, got {duration_s}")
    allowed = EVENTS_BY_LOCOMOTION[locomotion]
    rng = np.random.default_rng(seed)
    if events is None:
        count = int(rng.integers(1, 4))
        chosen = [str(rng.choice(EMERGENCY_EVENTS[locomotion]))]
        chosen += [str(rng.choice(allowed)) for _ in range(count - 1)]
        rng.shuffle(chosen)
        events = chosen
    for event in events:
        if event not in allowed:
            raise ValueError(
                f"event {event!r} is not possible when {locomotion.value}; choose from {allowed}"
            )
    noise = noise or CameraNoise()
    scale = rng.uniform(0.88, 1.08)
    seated = locomotion is Locomotion.WHEELCHAIR
    follow_z = rng.uniform(1.9, 2.3) if seated else rng.uniform(2.6, 3.1)
    b = Builder(rng=rng, scale=scale, locomotion=locomotion, follow_z=follow_z)
    start = np.zeros(len(PARAMS))
    start[P["x"]] = rng.uniform(-0.15, 0.15)
    start[P["z"]] = follow_z
    start = pose(start, scale, **(SIT_WHEELCHAIR if seated else {}))
    b.segments.append(("sitting_wheelchair" if seated else "standing", start[None, :]))
    b.segments[0] = (b.segments[0][0], upright(b)[None, :] if not seated else start[None, :])
    budget = max(duration_s - 4.0 * (len(events) + 1), 0.0)
    gaps = rng.dirichlet(np.ones(len(events) + 1)) * budget + 2.0
    base_activity(b, gaps[0])
    for event, gap in zip(events, gaps[1:], strict=True):
        EVENTS[event](b)
        base_activity(b, gap)
    labels = [label for label, seg in b.segments for _ in range(len(seg))]
    params = np.concatenate([seg for _, seg in b.segments])
    need = round(duration_s * FPS)
    if len(labels) < need:
        base_activity(b, (need - len(labels)) / FPS + 1 / FPS)
        labels = [label for label, seg in b.segments for _ in range(len(seg))]
        params = np.concatenate([seg for _, seg in b.segments])
    n = len(labels)

    world = [body_points(params, scale)]
    for _ in range(n_people - 1):
        other_scale = rng.uniform(0.9, 1.1)
        world.append(body_points(bystander_params(rng, n, other_scale, follow_z), other_scale))
    rendered = [render(w, rng, noise) for w in world]
    for i in range(len(rendered)):
        for j in range(len(rendered)):
            if i != j:
                occlude(rendered[j][0], rendered[j][1], rendered[i][0], rendered[i][1])

    order = rng.permutation(n_people)  # the patient is not always person 0
    people: list[list[SkeletonFrame | None]] = []
    for idx in order:
        keypoints, depth = rendered[idx]
        visible = (keypoints[:, :, 2] > 0).sum(-1) >= MIN_VISIBLE_KEYPOINTS
        floor = floor_measures_many(keypoints, depth, CAMERA_MOUNT)
        people.append(
            [
                SkeletonFrame(keypoints[t], depth[t], timestamp=t / FPS, floor=floor[t])
                if visible[t]
                else None
                for t in range(n)
            ]
        )
    patient_index = int(np.flatnonzero(order == 0)[0])

    chest_world = world[0][:, INDEX["neck"]] * 0.7 + world[0][:, INDEX["mid_hip"]] * 0.3
    chest_px, chest_depth = project(chest_world)
    side = FOCAL_PX * MARKER_SIZE_M / np.where(chest_depth > 0.3, chest_depth, np.nan)
    marker = np.concatenate([chest_px, side[:, None]], axis=-1)
    patient_seen = np.array([f is not None for f in people[patient_index]])
    marker[~patient_seen] = np.nan
    return GeneratedTransport(
        locomotion=locomotion,
        seed=seed,
        fps=FPS,
        frames_per_person=people,
        patient_index=patient_index,
        labels=labels,
        events=tuple(events),
        marker_px=marker.astype(np.float32),
    )

"""Per-frame feature vectors from canonical skeletons, streaming and batch with identical results.

Pose part (single frame): keypoints centred on the hips and divided by the skeleton's bounding-box
diagonal (scale invariant), the keypoint confidences (a missing keypoint is an explicit 0 there,
its coordinates are 0 and never mistaken for a real position), uprightness of the torso, bounding
box aspect, head height, and depth in metres with a has-depth flag (0 where unknown). Where the
frame carries floor measures (vigil.floor: the body's top and centre height above the floor, the
share of it near the floor), those too, with a has-floor flag: a fall ends on the floor, a
deliberate lie-down usually on a bed, and the depth camera sees the difference directly.

Temporal part: how fast the body got where it is. For horizons of 0.2-1.6 s, the change of body
centre height, horizontal position, size, aspect, uprightness, head height and depth since the
latest frame at least that long ago (by timestamp), in units of the body size back then; plus
decaying peaks (time constants 1.5 s and 4 s) of the downward speeds, so that a fast drop is
remembered while the person lies still afterwards. That is what separates a fall from lying down
on purpose, which looks the same in a single frame. `above_floor` is the body centre's height
above the lowest keypoint of the earlier frame (the floor line under a standing person): a fall
ends on the floor, a deliberate lie-down usually on a bed. With floor measures, the drops of the
top and centre height above the floor (metres) join the changes and their decaying peaks.

Limb geometry (feature version 4): knee and hip bend, thigh and shank direction, and the lean of
the shoulders over the ankles, each with a has-flag, and their changes over 0.2-0.8 s. Bending
over to pick something up folds the hips over straight knees, sitting down folds both while the
body stays over its feet, and in URFD's falls the knees buckle as the body drops and leans: the
centre and floor heights alone drop alike in all of them (docs/detection.md).

Descent memory (feature version 5): the fastest 0.4 s drop of the body's top above the floor
since the top was last at standing or sitting height, held for as long as the person stays down,
and the seconds since then. The decaying peaks forget a fall within seconds, so a person lying on
the floor for a while looked the same whether they fell or lay down slowly; this remembers how
they got there.

Frames with too few keypoints (fewer than MIN_KEYPOINTS; e.g. the pose estimator found nobody)
repeat the last usable pose with zero motion and set the `held` flag: the decision holds.
"""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np

from vigil.skeleton import INDEX, N_FLOOR, N_KEYPOINTS, SkeletonFrame

FEATURE_VERSION = 6
MIN_KEYPOINTS = 4
HORIZONS_S: tuple[float, ...] = (0.2, 0.4, 0.8, 1.6, 3.2)
DELTA_LIMIT = 5.0  # body sizes (or log units): beyond this a change is a tracking glitch
PEAK_TAUS_S: tuple[float, ...] = (1.5, 4.0)
MEMORY_FLOOR = 1e-3  # decaying memories below this are 0 (float32-safe for exported trees)
MISSING_TAU_S = 1.0  # time constant of the decaying share of frames without a usable pose
SINCE_SEEN_LIMIT_S = 3.0
STANDING_TOP_M = 1.0  # the body's top above the floor above this: standing or sitting upright
SINCE_STANDING_LIMIT_S = 10.0
_HIPS = [INDEX["mid_hip"], INDEX["r_hip"], INDEX["l_hip"]]
_NECK, _MID_HIP = INDEX["neck"], INDEX["mid_hip"]
_SHOULDERS, _HIP_PAIR = [INDEX["r_shoulder"], INDEX["l_shoulder"]], [INDEX["r_hip"], INDEX["l_hip"]]
_ANKLES = [INDEX["r_ankle"], INDEX["l_ankle"]]
_LEGS = tuple(
    (INDEX[f"{side}_shoulder"], INDEX[f"{side}_hip"], INDEX[f"{side}_knee"], INDEX[f"{side}_ankle"])
    for side in ("r", "l")
)
# Limb geometry (image plane; each the mean over the sides where its keypoints are present):
# knee and hip bend (0 straight, 2 folded), thigh and shank pointing down (1 vertical, 0
# horizontal), lean of the shoulders-over-ankles line (1 upright): how the body folds as it goes
# down, which the heights alone do not tell.
LIMBS = ("knee_bend", "hip_bend", "thigh_down", "shank_down", "lean")

# Per-frame scalar quantities tracked over time (columns of the "state" array).
_STATE = (
    "cx",
    "cy",
    "scale",
    "aspect",
    "upright",
    "top",
    "depth",
    "has_depth",
    "seen",
    "bottom",
    "seen_at",
    "visible",
    "floor_top",
    "floor_centre",
    "has_floor",
    *LIMBS,
    *(f"has_{limb}" for limb in LIMBS),
)
_S = {name: i for i, name in enumerate(_STATE)}
_LIMB_STATE = slice(_S[LIMBS[0]], _S[LIMBS[-1]] + 1)
_LIMB_SEEN = slice(_S[f"has_{LIMBS[0]}"], _S[f"has_{LIMBS[-1]}"] + 1)
_DELTAS = (
    "d_down",
    "d_side",
    "d_logscale",
    "d_aspect",
    "d_upright",
    "d_top",
    "d_depth",
    "above_floor",
    "d_visible",
    "d_floor_top",
    "d_floor_centre",
    *(f"d_{limb}" for limb in LIMBS),
)
# Limbs change shape within a second; their changes over longer horizons only added noise.
LIMB_HORIZON_LIMIT_S = 0.8
_LIMB_DELTAS = frozenset(f"d_{limb}" for limb in LIMBS)
_HORIZON_COLUMNS = {
    h: np.array(
        [i for i, d in enumerate(_DELTAS) if h <= LIMB_HORIZON_LIMIT_S or d not in _LIMB_DELTAS]
    )
    for h in HORIZONS_S
}
# Downward speeds whose decaying peaks are kept: centre drop, head drop, loss of uprightness.
# Loss of keypoints: a body hitting the floor is often lost by the pose estimator.
_PEAKED = ("d_down", "d_top", "d_upright", "d_visible", "d_floor_top", "d_floor_centre")
# Stream memory: time since the last usable pose and the decaying share of frames without one;
# the fastest 0.4 s drop of the top above the floor since it was last at standing height, and
# the time since then (module docstring).
_MEMORY = ("since_seen", "missing", "floor_descent", "floor_since_standing")
_DESCENT_HORIZON_S = 0.4


def _names() -> tuple[str, ...]:
    pose = [f"{axis}_{i}" for i in range(N_KEYPOINTS) for axis in ("x", "y")]
    pose += [f"conf_{i}" for i in range(N_KEYPOINTS)]
    pose += ["aspect", "upright", "top", "depth", "has_depth", "held"]
    temporal = [f"{_DELTAS[i]}@{h}" for h in HORIZONS_S for i in _HORIZON_COLUMNS[h]]
    temporal += [f"peak_{p}@{tau}" for tau in PEAK_TAUS_S for p in _PEAKED]
    temporal += list(_MEMORY)
    limbs = [*LIMBS, *(f"has_{limb}" for limb in LIMBS)]
    floor = ["floor_top", "floor_centre", "near_floor", "has_floor"]
    return tuple(pose + temporal + limbs + floor)


FEATURE_NAMES: tuple[str, ...] = _names()
N_POSE = N_KEYPOINTS * 3 + 6
N_LIMB = 2 * len(LIMBS)  # values and has-flags
#: The features made from floor measures (`above_floor@h` is made from keypoints, not these).
FLOOR_FEATURES = frozenset(
    name for name in FEATURE_NAMES if "floor_" in name or name in ("near_floor", "has_floor")
)
#: How often and how long one pose estimator loses a person: its habit, not the patient's. The
#: training data's MoveNet loses people in other frames than MediaPipe on a robot does (a model
#: that learnt "no pose lately" from MoveNet did not alarm on a MediaPipe video of a fall), so the
#: models meant for any camera and estimator (set `keypoints`) leave them out (feature version 6).
ESTIMATOR_DROPOUT_FEATURES = frozenset({"since_seen", "missing"})
FEATURE_SETS: dict[str, np.ndarray] = {
    "full": np.arange(len(FEATURE_NAMES)),
    "pose": np.arange(N_POSE),  # single-frame keypoint features only, as in the paper
    # For cameras without a known pose over the floor and any pose estimator: everything but the
    # floor measures and the estimator's dropout memory.
    "keypoints": np.array(
        [
            i
            for i, n in enumerate(FEATURE_NAMES)
            if n not in FLOOR_FEATURES and n not in ESTIMATOR_DROPOUT_FEATURES
        ]
    ),
}
#: Feature sets whose models need floor measures in the frames (vigil.floor).
NEEDS_FLOOR = frozenset({"full"})
_MAX_HORIZON = max(HORIZONS_S)
_HORIZONS = np.array(HORIZONS_S)
_TEMPORAL_START = FEATURE_NAMES.index(f"{_DELTAS[0]}@{HORIZONS_S[0]}")
_PEAK_SOURCE = [FEATURE_NAMES.index(f"{p}@0.4") - _TEMPORAL_START for p in _PEAKED]
_DESCENT_SOURCE = FEATURE_NAMES.index(f"d_floor_top@{_DESCENT_HORIZON_S}") - _TEMPORAL_START


def _pose_and_state(
    keypoints: np.ndarray, depth: np.ndarray, floor: np.ndarray, timestamps: np.ndarray
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """(n, 25, 3), (n, 25), (n, 3) -> pose features (n, N_POSE - 1 + N_LIMB + N_FLOOR + 1) without
    `held`, state (n, len(_STATE)), and a usable-frame mask."""
    n = keypoints.shape[0]
    conf = keypoints[:, :, 2].astype(np.float64)
    xy = keypoints[:, :, :2].astype(np.float64)
    present = (conf > 0) & np.isfinite(xy).all(axis=2)  # a NaN coordinate counts as missing
    xy = np.where(present[..., None], xy, 0.0)
    conf = np.where(present, conf, 0.0)
    count = present.sum(axis=1)
    usable = count >= MIN_KEYPOINTS

    hips_present = present[:, _HIPS]
    n_hips = hips_present.sum(axis=1)
    hip_centre = (xy[:, _HIPS] * hips_present[..., None]).sum(axis=1) / np.maximum(n_hips, 1)[
        :, None
    ]
    all_centre = (xy * present[..., None]).sum(axis=1) / np.maximum(count, 1)[:, None]
    centre = np.where((n_hips > 0)[:, None], hip_centre, all_centre)

    big = np.where(present[..., None], xy, np.inf)
    small = np.where(present[..., None], xy, -np.inf)
    lo, hi = big.min(axis=1), small.max(axis=1)
    extent = np.where(usable[:, None], hi - lo, 1.0)
    width, height = np.maximum(extent[:, 0], 1e-6), np.maximum(extent[:, 1], 1e-6)
    scale = np.sqrt(width**2 + height**2)
    aspect = np.log(height / width)
    top = np.where(usable, (centre[:, 1] - lo[:, 1]) / scale, 0.0)

    neck, neck_ok = _point(xy, present, _NECK, _SHOULDERS)
    hip, hip_ok = _point(xy, present, _MID_HIP, _HIP_PAIR)
    torso = hip - neck
    torso_len = np.maximum(np.sqrt((torso**2).sum(axis=1)), 1e-6)
    upright = np.where(neck_ok & hip_ok, torso[:, 1] / torso_len, 0.0)

    finite_depth = present & np.isfinite(depth)
    n_depth = finite_depth.sum(axis=1)
    depth_m = np.where(finite_depth, depth, 0.0).sum(axis=1) / np.maximum(n_depth, 1)
    has_depth = (n_depth > 0).astype(np.float64)

    rel = np.where(present[..., None], (xy - centre[:, None, :]) / scale[:, None, None], 0.0)
    limbs, limbs_seen = _limbs(xy, present)
    floor = floor.astype(np.float64)
    has_floor = np.isfinite(floor).all(axis=1)
    floor = np.where(has_floor[:, None], floor, 0.0)
    pose = np.concatenate(
        [
            rel.reshape(n, -1),
            conf,
            np.stack([aspect, upright, top, depth_m, has_depth], axis=1),
            limbs,
            limbs_seen,
            floor,
            has_floor[:, None],
        ],
        axis=1,
    )
    seen = usable.astype(np.float64)
    bottom = np.where(usable, hi[:, 1], 0.0)
    state = np.stack(
        [
            *(centre[:, 0], centre[:, 1], scale, aspect, upright, top, depth_m, has_depth, seen),
            *(bottom, timestamps, count / N_KEYPOINTS),
            *(floor[:, 0], floor[:, 1], has_floor),
            *limbs.T,
            *limbs_seen.T,
        ],
        axis=1,
    )
    return pose, state, usable


def _cos(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    norms = np.sqrt((a**2).sum(axis=-1) * (b**2).sum(axis=-1))
    return (a * b).sum(axis=-1) / np.maximum(norms, 1e-9)


def _down(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """How far the segment a -> b points down the image: 1 straight down, 0 horizontal."""
    v = b - a
    return v[..., 1] / np.maximum(np.sqrt((v**2).sum(axis=-1)), 1e-9)


def _limbs(xy: np.ndarray, present: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """(n, 25, 2), (n, 25) -> LIMBS values (n, 5) (0 where unknown) and their has-flags (n, 5)."""
    values, seen = [], []
    for shoulder, hip, knee, ankle in _LEGS:
        s, h, k, a = (xy[:, j] for j in (shoulder, hip, knee, ankle))
        ps, ph, pk, pa = (present[:, j] for j in (shoulder, hip, knee, ankle))
        values.append(
            np.stack([1 + _cos(h - k, a - k), 1 + _cos(s - h, k - h), _down(h, k), _down(k, a)], 1)
        )
        seen.append(np.stack([ph & pk & pa, ps & ph & pk, ph & pk, pk & pa], 1))
    values, seen = np.stack(values), np.stack(seen)  # (sides, n, 4)
    count = seen.sum(axis=0)
    per_leg = np.where(seen, values, 0.0).sum(axis=0) / np.maximum(count, 1)
    shoulders_ok = present[:, _SHOULDERS].all(axis=1)
    ankles_ok = present[:, _ANKLES].all(axis=1)
    lean = -_down(xy[:, _ANKLES].mean(axis=1), xy[:, _SHOULDERS].mean(axis=1))
    lean_ok = shoulders_ok & ankles_ok
    has = np.concatenate([count > 0, lean_ok[:, None]], axis=1)
    limbs = np.concatenate([per_leg, lean[:, None]], axis=1)
    return np.where(has, limbs, 0.0), has.astype(np.float64)


def _point(xy, present, index, pair) -> tuple[np.ndarray, np.ndarray]:
    """A keypoint, or the midpoint of its pair when it is missing (as OpenPose derives it)."""
    own = present[:, index]
    pair_ok = present[:, pair[0]] & present[:, pair[1]]
    mid = (xy[:, pair[0]] + xy[:, pair[1]]) / 2
    return np.where(own[:, None], xy[:, index], mid), own | pair_ok


def _hold(pose: np.ndarray, state: np.ndarray, usable: np.ndarray, last: tuple | None):
    """Forward-fill unusable frames from the last usable one (or `last` carried in from before)."""
    n = len(usable)
    source = np.where(usable, np.arange(n), -1)
    source = np.maximum.accumulate(source) if n else source
    pose_out, state_out = pose.copy(), state.copy()
    filled = source >= 0
    pose_out[filled] = pose[source[filled]]
    state_out[filled] = state[source[filled]]
    if last is not None:
        pose_out[~filled], state_out[~filled] = last[0], last[1]
    else:
        pose_out[~filled], state_out[~filled] = 0.0, 0.0
        state_out[~filled, _S["scale"]] = 1.0
    return pose_out, state_out


def _deltas(state_now: np.ndarray, state_then: np.ndarray, horizon) -> np.ndarray:
    """(m, len(_STATE)) pairs at one horizon, or at (m,) horizons -> (m, len(_DELTAS)) in body
    sizes (the larger of then and now, so one frame with a few clustered keypoints cannot blow a
    change up); 0 if no pose was seen then.
    When the earlier pose is older than the horizon (the person was not detected in between), the
    change is scaled down to the horizon, so reappearing elsewhere does not look like a fast drop.
    """
    elapsed = state_now[:, _S["seen_at"]] - state_then[:, _S["seen_at"]]
    pace = np.minimum(1.0, 1.5 * horizon / np.maximum(elapsed, 1e-9))[:, None]
    ref = np.maximum(state_then[:, _S["scale"]], state_now[:, _S["scale"]])
    both_seen = (state_then[:, _S["seen"]] * state_now[:, _S["seen"]])[:, None]
    both_floor = state_then[:, _S["has_floor"]] * state_now[:, _S["has_floor"]]
    deltas = np.stack(
        [
            (state_now[:, _S["cy"]] - state_then[:, _S["cy"]]) / ref,
            np.abs(state_now[:, _S["cx"]] - state_then[:, _S["cx"]]) / ref,
            np.log(state_now[:, _S["scale"]] / state_then[:, _S["scale"]]),
            state_now[:, _S["aspect"]] - state_then[:, _S["aspect"]],
            state_then[:, _S["upright"]] - state_now[:, _S["upright"]],
            state_then[:, _S["top"]] - state_now[:, _S["top"]],
            (state_now[:, _S["depth"]] - state_then[:, _S["depth"]])
            * state_now[:, _S["has_depth"]]
            * state_then[:, _S["has_depth"]],
            # body centre above the lowest keypoint back then (the floor under a standing person)
            (state_then[:, _S["bottom"]] - state_now[:, _S["cy"]]) / ref,
            state_then[:, _S["visible"]] - state_now[:, _S["visible"]],
            (state_then[:, _S["floor_top"]] - state_now[:, _S["floor_top"]]) * both_floor,
            (state_then[:, _S["floor_centre"]] - state_now[:, _S["floor_centre"]]) * both_floor,
            *(
                (state_now[:, _LIMB_STATE] - state_then[:, _LIMB_STATE])
                * state_now[:, _LIMB_SEEN]
                * state_then[:, _LIMB_SEEN]
            ).T,
        ],
        axis=1,
    )
    return np.clip(deltas * pace, -DELTA_LIMIT, DELTA_LIMIT) * both_seen


def _lag_index(timestamps: np.ndarray, now: np.ndarray, horizon: float) -> np.ndarray:
    """Index of the latest frame at least `horizon` seconds before each `now` (else the first)."""
    return np.maximum(np.searchsorted(timestamps, now - horizon, side="right") - 1, 0)


def _peak_step(peaks: np.ndarray, speeds: np.ndarray, dt: float) -> np.ndarray:
    decay = np.exp(-dt / np.asarray(PEAK_TAUS_S))[:, None]
    peaks = np.maximum(speeds[None, :], peaks * decay)
    # Decayed remnants are flushed to 0: a tree split between 1e-20 and 0 would not survive the
    # float32 ONNX graph.
    return np.where(np.abs(peaks) < MEMORY_FLOOR, 0.0, peaks)


class _Memory:
    """Recurrent per-stream quantities (the same step in batch and streaming extraction)."""

    def __init__(self) -> None:
        self.missing = 0.0
        self.descent = 0.0
        self.standing_at: float | None = None

    def step(
        self, state: np.ndarray, usable: bool, dt: float, now: float, top_drop: float
    ) -> np.ndarray:
        """`top_drop`: this frame's drop of the top above the floor over _DESCENT_HORIZON_S."""
        keep = float(np.exp(-dt / MISSING_TAU_S))
        self.missing = keep * self.missing + (1.0 - keep) * (0.0 if usable else 1.0)
        self.missing = round(self.missing, 3) if self.missing >= MEMORY_FLOOR else 0.0
        since_seen = now - state[_S["seen_at"]] if state[_S["seen"]] > 0 else SINCE_SEEN_LIMIT_S
        if state[_S["has_floor"]] > 0:
            if state[_S["floor_top"]] > STANDING_TOP_M:
                self.descent, self.standing_at = 0.0, now
            self.descent = max(self.descent, float(top_drop))
        since_standing = (
            SINCE_STANDING_LIMIT_S if self.standing_at is None else now - self.standing_at
        )
        return np.array(
            [
                min(since_seen, SINCE_SEEN_LIMIT_S),
                self.missing,
                self.descent,
                min(since_standing, SINCE_STANDING_LIMIT_S),
            ]
        )


def _as_arrays(frames: Sequence[SkeletonFrame]):
    keypoints = np.stack([f.keypoints for f in frames]).astype(np.float32)
    depth = np.stack([f.depth for f in frames]).astype(np.float32)
    floor = np.stack([f.floor for f in frames]).astype(np.float32)
    timestamps = np.array([f.timestamp for f in frames], np.float64)
    return keypoints, depth, timestamps, floor


def _check_time(timestamps: np.ndarray, previous: float | None) -> None:
    if (len(timestamps) > 1 and np.any(np.diff(timestamps) < 0)) or (
        previous is not None and len(timestamps) and timestamps[0] < previous
    ):
        raise ValueError("frame timestamps must not decrease; call reset() for a new stream")


def extract_arrays(
    keypoints: np.ndarray,
    depth: np.ndarray | None,
    timestamps: np.ndarray,
    feature_set: str = "full",
    floor: np.ndarray | None = None,
) -> np.ndarray:
    """Vectorised features of one stream: keypoints (n, 25, 3), depth (n, 25) or None,
    timestamps (n,), floor measures (n, 3) or None -> (n, d)."""
    keypoints = np.asarray(keypoints, np.float32)
    n = keypoints.shape[0]
    if depth is None:
        depth = np.full((n, N_KEYPOINTS), np.nan, np.float32)
    if floor is None:
        floor = np.full((n, N_FLOOR), np.nan, np.float32)
    timestamps = np.asarray(timestamps, np.float64)
    _check_time(timestamps, None)
    if n == 0:
        return np.zeros((0, len(FEATURE_SETS[feature_set])), np.float32)
    pose, state, usable = _pose_and_state(
        keypoints, np.asarray(depth, np.float32), np.asarray(floor, np.float32), timestamps
    )
    pose, state = _hold(pose, state, usable, None)
    held = (~usable).astype(np.float64)[:, None]
    temporal = []
    for horizon in HORIZONS_S:
        then = _lag_index(timestamps, timestamps, horizon)
        delta = _deltas(state, state[then], horizon)[:, _HORIZON_COLUMNS[horizon]]
        temporal.append(np.where(usable[:, None], delta, 0.0))
    temporal = np.concatenate(temporal, axis=1)
    peaks = np.zeros((n, len(PEAK_TAUS_S), len(_PEAKED)))
    speeds = temporal[:, _PEAK_SOURCE]
    current = np.zeros((len(PEAK_TAUS_S), len(_PEAKED)))
    memory, memories = _Memory(), np.zeros((n, len(_MEMORY)))
    for i in range(n):
        dt = timestamps[i] - timestamps[i - 1] if i else 0.0
        current = _peak_step(current, speeds[i], dt)
        peaks[i] = current
        memories[i] = memory.step(
            state[i], bool(usable[i]), dt, float(timestamps[i]), temporal[i, _DESCENT_SOURCE]
        )
    features = _assemble(pose, held, temporal, peaks.reshape(n, -1), memories)
    return features[:, FEATURE_SETS[feature_set]].astype(np.float32)


def _assemble(pose, held, temporal, peaks, memories) -> np.ndarray:
    keypoint_pose, limbs = pose[:, : N_POSE - 1], pose[:, N_POSE - 1 : N_POSE - 1 + N_LIMB]
    floor = pose[:, N_POSE - 1 + N_LIMB :]
    return np.concatenate([keypoint_pose, held, temporal, peaks, memories, limbs, floor], axis=1)


def extract_sequence(frames: Sequence[SkeletonFrame], feature_set: str = "full") -> np.ndarray:
    """Features of a whole stream at once; identical to pushing the frames one by one."""
    if not frames:
        return np.zeros((0, len(FEATURE_SETS[feature_set])), np.float32)
    keypoints, depth, timestamps, floor = _as_arrays(frames)
    return extract_arrays(keypoints, depth, timestamps, feature_set, floor)


class FeatureExtractor:
    """Streaming features of one person: push frames in time order, reset between streams."""

    def __init__(self, feature_set: str = "full") -> None:
        if feature_set not in FEATURE_SETS:
            raise ValueError(f"unknown feature_set {feature_set!r}; known: {sorted(FEATURE_SETS)}")
        self.feature_set = feature_set
        self.columns_ = FEATURE_SETS[feature_set]
        self.reset()

    @property
    def n_features(self) -> int:
        return len(self.columns_)

    def reset(self) -> None:
        self._times: list[float] = []
        self._states: list[np.ndarray] = []
        self._last: tuple[np.ndarray, np.ndarray] | None = None
        self._peaks = np.zeros((len(PEAK_TAUS_S), len(_PEAKED)))
        self._memory = _Memory()

    def push(self, frame: SkeletonFrame) -> np.ndarray:
        t = float(frame.timestamp)
        _check_time(np.array([t]), self._times[-1] if self._times else None)
        pose, state, usable = _pose_and_state(
            frame.keypoints[None].astype(np.float32),
            frame.depth[None].astype(np.float32),
            frame.floor[None].astype(np.float32),
            np.array([t]),
        )
        pose, state = _hold(pose, state, usable, self._last)
        self._last = (pose[0], state[0])
        dt = t - self._times[-1] if self._times else 0.0
        self._times.append(t)
        self._states.append(state[0])
        while len(self._times) > 1 and self._times[1] <= t - _MAX_HORIZON:
            self._times.pop(0)
            self._states.pop(0)
        # All horizons in one _deltas call: per frame, numpy's call overhead is what costs.
        then = _lag_index(np.array(self._times), t, _HORIZONS)
        deltas = _deltas(
            np.repeat(state, len(_HORIZONS), axis=0),
            np.stack([self._states[i] for i in then]),
            _HORIZONS,
        )
        temporal = np.concatenate(
            [deltas[k, _HORIZON_COLUMNS[h]] for k, h in enumerate(HORIZONS_S)]
        )[None]
        if not usable[0]:
            temporal = np.zeros_like(temporal)
        self._peaks = _peak_step(self._peaks, temporal[0, _PEAK_SOURCE], dt)
        held = (~usable).astype(np.float64)[:, None]
        top_drop = temporal[0, _DESCENT_SOURCE]
        memory = self._memory.step(state[0], bool(usable[0]), dt, t, top_drop)[None]
        features = _assemble(pose, held, temporal, self._peaks.reshape(1, -1), memory)
        return features[0, self.columns_].astype(np.float32)


def window_index(group: np.ndarray, window: int) -> np.ndarray:
    """(n, window) row indices of each frame's last `window` frames within its own stream,
    padded at a stream's start with its first frame (as vigil.runtime pads a new stream)."""
    group = np.asarray(group)
    n = len(group)
    change = np.ones(n, bool)
    change[1:] = group[1:] != group[:-1]
    stream_start = np.maximum.accumulate(np.where(change, np.arange(n), 0)) if n else change
    offsets = np.arange(-window + 1, 1)
    return np.maximum(np.arange(n)[:, None] + offsets[None, :], stream_start[:, None])

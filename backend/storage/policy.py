"""The retention policy: which robot frames older than the cutoff are kept, and why.

Kept forever:
- every frame of a video with labels (a segment that is not deleted) or with a split,
- every frame of a video a registered model's lineage names (`training_videos`),
- every frame of the alarm's robot within [first frame - before_s, last frame + after_s] of
  each alarm (an alarm without frame times uses its raise time),
- frames that are not robot frames (imported datasets: their ts is not a wall-clock time).
Kept for now: frames newer than the cutoff (now - retention_days), and, when a downsampled copy
is on, every step-th frame of a video (step = video fps / downsample fps) for
retention_downsample_days more days. Everything else older than the cutoff is dropped.

`PolicyFacts` is loaded once per run (`backend.storage.queries.policy_facts`); `reason` is a pure
function of one frame (the benchmark's row by row check uses it), and `reasons` is the same rule
over whole columns with numpy (the retention runs use it: a day of frames is chosen without a
Python step per row). tests/backend/storage/test_policy.py checks that both give the same reason
for every frame of crafted data.
"""

from __future__ import annotations

import bisect
from dataclasses import dataclass, field

import numpy as np

DAY_S = 86400.0

RECENT = "recent"
ALARM_WINDOW = "alarm_window"
LABELLED = "labelled"
SPLIT = "split"
LINEAGE = "lineage"
DOWNSAMPLED = "downsampled"
NOT_ROBOT = "not_robot"
KEPT_REASONS = (ALARM_WINDOW, LABELLED, SPLIT, LINEAGE, DOWNSAMPLED)
#: `PolicyFacts.reasons` codes: the index into this tuple (0: dropped).
REASON_CODES: tuple[str | None, ...] = (
    None,
    NOT_ROBOT,
    RECENT,
    LABELLED,
    SPLIT,
    LINEAGE,
    ALARM_WINDOW,
    DOWNSAMPLED,
)
DROPPED_CODE = 0
_CODE = {reason: code for code, reason in enumerate(REASON_CODES)}


@dataclass(frozen=True)
class RetentionPolicy:
    days: float = 30
    alarm_before_s: float = 60
    alarm_after_s: float = 30
    downsample_fps: float = 0
    downsample_days: float = 60

    @classmethod
    def from_settings(cls, settings) -> RetentionPolicy:
        return cls(
            days=settings.retention_days,
            alarm_before_s=settings.retention_alarm_before_s,
            alarm_after_s=settings.retention_alarm_after_s,
            downsample_fps=settings.retention_downsample_fps,
            downsample_days=settings.retention_downsample_days,
        )

    def cutoff(self, now: float) -> float:
        return now - self.days * DAY_S

    def downsample_until(self, now: float) -> float:
        """Frames at or after this time may be kept as the downsampled copy."""
        return self.cutoff(now) - self.downsample_days * DAY_S

    def as_dict(self) -> dict:
        return {
            "days": self.days,
            "alarm_before_s": self.alarm_before_s,
            "alarm_after_s": self.alarm_after_s,
            "downsample_fps": self.downsample_fps,
            "downsample_days": self.downsample_days,
        }


@dataclass
class Windows:
    """Merged, sorted [start, end] intervals of one robot."""

    starts: list[float] = field(default_factory=list)
    ends: list[float] = field(default_factory=list)

    def covers(self, ts: float) -> bool:
        i = bisect.bisect_right(self.starts, ts) - 1
        return i >= 0 and ts <= self.ends[i]


def merge_windows(intervals: list[tuple[float, float]]) -> Windows:
    merged = Windows()
    for start, end in sorted(intervals):
        if merged.ends and start <= merged.ends[-1]:
            merged.ends[-1] = max(merged.ends[-1], end)
        else:
            merged.starts.append(start)
            merged.ends.append(end)
    return merged


@dataclass
class PolicyFacts:
    policy: RetentionPolicy
    now: float
    protected_videos: dict[int, str]  # video id -> labelled | split | lineage
    windows: dict[str, Windows]  # robot id -> alarm windows
    video_steps: dict[int, int]  # video id -> keep every step-th frame (downsampled copy)

    @property
    def cutoff(self) -> float:
        """Frames go by whole UTC days: a day goes once all of it is older than the policy's
        cutoff (a PostgreSQL day partition is replaced as a whole; SQLite follows the same rule
        so both keep the same frames)."""
        return day_of(self.policy.cutoff(self.now)) * DAY_S

    def reason(self, video_id: int, robot_id: str | None, ts: float, index: int) -> str | None:
        """Why the frame stays, or None when the policy drops it."""
        if robot_id is None:
            return NOT_ROBOT
        if ts >= self.cutoff:
            return RECENT
        protected = self.protected_videos.get(video_id)
        if protected is not None:
            return protected
        windows = self.windows.get(robot_id)
        if windows is not None and windows.covers(ts):
            return ALARM_WINDOW
        if (
            self.policy.downsample_fps > 0
            and ts >= self.policy.downsample_until(self.now)
            and index % self.video_steps.get(video_id, 1) == 0
        ):
            return DOWNSAMPLED
        return None

    def reasons(
        self,
        video_ids: np.ndarray,
        robot_ids: list[str | None] | np.ndarray,
        ts: np.ndarray,
        index: np.ndarray,
    ) -> np.ndarray:
        """`reason` of many frames at once: an int8 array of REASON_CODES indices (0: the
        policy drops the frame). The same rule, in the same order of precedence."""
        video_ids = np.asarray(video_ids, dtype=np.int64)
        ts = np.asarray(ts, dtype=np.float64)
        index = np.asarray(index, dtype=np.int64)
        n = len(ts)
        codes = np.zeros(n, dtype=np.int8)
        if n == 0:
            return codes
        robots = np.asarray(robot_ids, dtype=object)
        undecided = np.ones(n, dtype=bool)

        def decide(mask: np.ndarray, reason: str) -> None:
            mask &= undecided
            codes[mask] = _CODE[reason]
            undecided[mask] = False

        decide(robots == None, NOT_ROBOT)  # noqa: E711 - elementwise comparison
        decide(ts >= self.cutoff, RECENT)
        if self.protected_videos:
            protected = {video: _CODE[r] for video, r in self.protected_videos.items()}
            values, hit = _per_video(protected, video_ids, np.int8)
            hit &= undecided
            codes[hit] = values[hit]
            undecided[hit] = False
        if self.windows and undecided.any():
            covered = np.zeros(n, dtype=bool)
            numbers = {robot_id: k for k, robot_id in enumerate(self.windows)}
            robot_numbers = np.fromiter((numbers.get(r, -1) for r in robots), np.int32, n)
            for robot_id, windows in self.windows.items():
                rows = np.flatnonzero(undecided & (robot_numbers == numbers[robot_id]))
                if not len(rows) or not windows.starts:
                    continue
                starts = np.asarray(windows.starts, dtype=np.float64)
                ends = np.asarray(windows.ends, dtype=np.float64)
                at = ts[rows]
                i = np.searchsorted(starts, at, side="right") - 1  # bisect_right - 1
                inside = (i >= 0) & (at <= ends[np.maximum(i, 0)])
                covered[rows[inside]] = True
            decide(covered, ALARM_WINDOW)
        if self.policy.downsample_fps > 0 and undecided.any():
            steps = np.ones(n, dtype=np.int64)
            if self.video_steps:
                values, hit = _per_video(self.video_steps, video_ids, np.int64)
                steps[hit] = values[hit]
            later = ts >= self.policy.downsample_until(self.now)
            decide(later & (index % steps == 0), DOWNSAMPLED)
        return codes


def _per_video(mapping: dict[int, int], video_ids: np.ndarray, dtype) -> tuple[np.ndarray, ...]:
    """Per frame, `mapping`'s value for its video (where it has one) and whether it has one."""
    keys = np.array(sorted(mapping), dtype=np.int64)
    values = np.array([mapping[k] for k in keys], dtype=dtype)
    slot = np.minimum(np.searchsorted(keys, video_ids), len(keys) - 1)
    return values[slot], keys[slot] == video_ids


def downsample_step(video_fps: float, downsample_fps: float) -> int:
    if downsample_fps <= 0 or video_fps <= downsample_fps:
        return 1
    return max(1, round(video_fps / downsample_fps))


def alarm_intervals(
    rows: list[tuple[str, float | None, float | None, float]], policy: RetentionPolicy
) -> dict[str, Windows]:
    """rows: (robot id, first frame ts, last frame ts, raised at as unix time)."""
    by_robot: dict[str, list[tuple[float, float]]] = {}
    for robot_id, first, last, raised in rows:
        start = first if first is not None else raised
        end = last if last is not None else start
        by_robot.setdefault(robot_id, []).append(
            (start - policy.alarm_before_s, end + policy.alarm_after_s)
        )
    return {robot: merge_windows(intervals) for robot, intervals in by_robot.items()}


def day_of(ts: float) -> int:
    """UTC day number (days since 1970-01-01); a frame at midnight belongs to the new day."""
    return int(ts // DAY_S)

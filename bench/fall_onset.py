"""How much of each URFD fall is labelled Emergency before the body visibly moves, on REAL data:
`python -m bench.fall_onset` (make bench-fall-onset) writes bench/results/fall_onset.json.

Every fall sequence labels 30 frames "falling" (official label 0) before "lying" (1). For each
fall, the onset is the first Emergency-labelled frame from which a quantity has moved by more
than a fraction of its value over the second before the first Emergency frame: the hip centre's
drop in body sizes (MoveNet keypoints; body size = vertical extent of the keypoints), or the
drop of URFD's depth height H (the person's top above the floor). Emergency frames before the
onset can only be caught by a detector that fires before that much movement; 1 - those frames /
all Emergency frames bounds the frame recall of a detector that needs it.

It also compares the falls' first moments with the daily activities: how far H (metres) goes
down in the first 0.2-0.5 s after a fall's first Emergency frame, and how many daily-activity
sequences go down as far in the same time somewhere in them (sitting down fast, bending, lying
down). Where many do, the drop so far cannot tell a fall yet.
"""

from __future__ import annotations

import argparse
import json
import warnings
from pathlib import Path

import numpy as np

from vigil.datasets import urfd
from vigil.skeleton import INDEX

RESULTS = Path(__file__).resolve().parent / "results" / "fall_onset.json"
FRACTIONS = (0.05, 0.1, 0.2)
DROP_WINDOWS_S = (0.2, 0.3, 0.4, 0.5)
END_FRAMES = 3  # the height at the end of a window: the median of its last 3 frames (glitches)
_HIPS = [INDEX["r_hip"], INDEX["l_hip"]]


def _onset(change: np.ndarray, first: int, fraction: float) -> int:
    moved = np.flatnonzero((np.arange(len(change)) >= first) & (np.nan_to_num(change) > fraction))
    return int(moved[0]) if moved.size else len(change)


def drop_within(height: np.ndarray, timestamps: np.ndarray, start: int, window_s: float) -> float:
    """How far `height` goes down in the `window_s` seconds after frame `start` (metres; NaN
    where unknown or the stream ends first). Both ends are medians of their last END_FRAMES
    frames, so a one-frame depth glitch does not count as a drop."""
    end = int(np.searchsorted(timestamps, timestamps[start] + window_s + 1e-6, side="right")) - 1
    if end <= start or timestamps[end] < timestamps[start] + window_s - 0.02:
        return float("nan")
    with warnings.catch_warnings():  # all-NaN stretches where the depth features are missing
        warnings.simplefilter("ignore", RuntimeWarning)
        before = np.nanmedian(height[max(0, start - END_FRAMES + 1) : start + 1])
        after = np.nanmedian(height[end - END_FRAMES + 1 : end + 1])
    return float(before - after)


def fastest_drop(height: np.ndarray, timestamps: np.ndarray, window_s: float) -> float:
    """The farthest `drop_within` `window_s` anywhere in a stream (NaN if none known)."""
    drops = [drop_within(height, timestamps, i, window_s) for i in range(len(height))]
    known = [d for d in drops if np.isfinite(d)]
    return max(known) if known else float("nan")


def compare_drops(fall_drops: dict[float, list[float]], adl_fastest: dict[float, list[float]]):
    """Per window: the median fall's drop and the daily activities dropping as far in as little
    time; the least that every daily activity drops in that time somewhere, and the falls that
    drop less than that in their first moments."""
    result = {}
    for window, drops in fall_drops.items():
        falls = np.array([d for d in drops if np.isfinite(d)])
        adl = np.array([d for d in adl_fastest[window] if np.isfinite(d)])
        median = float(np.median(falls))
        result[str(window)] = {
            "median_fall_drop_m": round(median, 3),
            "adl_dropping_as_far": int(np.sum(adl >= median)),
            "adl_fastest_drop_min_m": round(float(adl.min()), 3) if adl.size else None,
            "falls_dropping_less": int(np.sum(falls < adl.min())) if adl.size else 0,
        }
    return result


def measure(directory: Path | None = None) -> dict:
    before = {cue: dict.fromkeys(FRACTIONS, 0) for cue in ("hip_drop", "depth_height_drop")}
    onset_s = {cue: {f: [] for f in FRACTIONS} for cue in before}
    emergency_total = falling_total = 0
    sequences = urfd.load(directory)
    fall_drops = {w: [] for w in DROP_WINDOWS_S}
    adl_fastest = {
        w: [fastest_drop(s.floor[:, 0], s.timestamps, w) for s in sequences if not s.is_fall]
        for w in DROP_WINDOWS_S
    }
    for seq in (s for s in sequences if s.is_fall):
        emergency = np.flatnonzero(seq.target == urfd.EMERGENCY)
        first = int(emergency[0])
        emergency_total += emergency.size
        falling_total += int(np.sum(seq.urfd_label == 0))
        baseline = slice(max(0, first - 30), first + 1)
        present = seq.keypoints[:, :, 2] > 0
        y = np.where(present, seq.keypoints[:, :, 1], np.nan)
        with warnings.catch_warnings():  # frames where MoveNet found nobody are all NaN
            warnings.simplefilter("ignore", RuntimeWarning)
            size = np.nanmax(y, axis=1) - np.nanmin(y, axis=1)
            hip = np.nanmean(y[:, _HIPS], axis=1)
            hip_drop = (hip - np.nanmedian(hip[baseline])) / np.nanmedian(size[baseline])
            height = seq.floor[:, 0]
            height_drop = (np.nanmedian(height[baseline]) - height) / np.nanmedian(height[baseline])
        for window in DROP_WINDOWS_S:
            fall_drops[window].append(drop_within(height, seq.timestamps, first, window))
        for cue, change in (("hip_drop", hip_drop), ("depth_height_drop", height_drop)):
            for fraction in FRACTIONS:
                onset = _onset(change, first, fraction)
                before[cue][fraction] += onset - first
                if onset < len(change):
                    onset_s[cue][fraction].append(
                        float(seq.timestamps[onset] - seq.timestamps[first])
                    )
    return {
        "data": "REAL: URFD, the 30 falls (onsets) and 40 daily activities (drop speeds)",
        "emergency_frames": emergency_total,
        "falling_frames": falling_total,
        "emergency_frames_before_onset": {
            cue: {str(f): n for f, n in counts.items()} for cue, counts in before.items()
        },
        # Per fall, seconds from the first Emergency-labelled frame to the onset: the median over
        # the falls that reach it. A detector needing that much movement alarms no sooner.
        "median_onset_s": {
            cue: {str(f): round(float(np.median(v)), 3) if v else None for f, v in times.items()}
            for cue, times in onset_s.items()
        },
        "falls_reaching_onset": {
            cue: {str(f): len(v) for f, v in times.items()} for cue, times in onset_s.items()
        },
        "frame_recall_bound": {
            cue: {str(f): round(1 - n / emergency_total, 3) for f, n in counts.items()}
            for cue, counts in before.items()
        },
        # Seconds after a fall's first Emergency frame -> the median fall's drop of H in that
        # time (metres) and how many of the daily-activity sequences drop as far in as little
        # time somewhere; every daily activity drops at least `adl_fastest_drop_min_m` in that
        # time somewhere, and `falls_dropping_less` falls go down less than that in their first
        # that many seconds.
        "falls_total": len(fall_drops[DROP_WINDOWS_S[0]]),
        "adl_total": len(adl_fastest[DROP_WINDOWS_S[0]]),
        "drop_after_first_emergency": compare_drops(fall_drops, adl_fastest),
    }


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--urfd-dir", type=Path, default=None)
    parser.add_argument("--output", type=Path, default=RESULTS)
    args = parser.parse_args(argv)
    result = measure(args.urfd_dir)
    args.output.write_text(json.dumps(result, indent=2) + "\n")
    print(json.dumps(result, indent=2))
    return 0


if __name__ == "__main__":
    raise SystemExit(main())

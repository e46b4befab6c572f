"""How much of each URFD fall is labelled Emergency before the body visibly moves, on REAL data:
`python -m bench.fall_onset` (make bench-fall-onset) writes bench/results/fall_onset.json.

Every fall sequence labels 30 frames "falling" (official label 0) before "lying" (1). For each
fall, the onset is the first Emergency-labelled frame from which a quantity has moved by more
than a fraction of its value over the second before the first Emergency frame: the hip centre's
drop in body sizes (MoveNet keypoints; body size = vertical extent of the keypoints), or the
drop of URFD's depth height H (the person's top above the floor). Emergency frames before the
onset can only be caught by a detector that fires before that much movement; 1 - those frames /
all Emergency frames bounds the frame recall of a detector that needs it.
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
_HIPS = [INDEX["r_hip"], INDEX["l_hip"]]


def _onset(change: np.ndarray, first: int, fraction: float) -> int:
    moved = np.flatnonzero((np.arange(len(change)) >= first) & (np.nan_to_num(change) > fraction))
    return int(moved[0]) if moved.size else len(change)


def measure(directory: Path | None = None) -> dict:
    before = {cue: dict.fromkeys(FRACTIONS, 0) for cue in ("hip_drop", "depth_height_drop")}
    onset_s = {cue: {f: [] for f in FRACTIONS} for cue in before}
    emergency_total = falling_total = 0
    for seq in (s for s in urfd.load(directory) if s.is_fall):
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
        for cue, change in (("hip_drop", hip_drop), ("depth_height_drop", height_drop)):
            for fraction in FRACTIONS:
                onset = _onset(change, first, fraction)
                before[cue][fraction] += onset - first
                if onset < len(change):
                    onset_s[cue][fraction].append(
                        float(seq.timestamps[onset] - seq.timestamps[first])
                    )
    return {
        "data": "REAL: URFD, the 30 fall sequences",
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

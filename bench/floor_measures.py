"""Floor measures from keypoints against URFD's silhouette-based ones, on REAL data:
`python -m bench.floor_measures` (make bench-floor) writes bench/results/floor_measures.json.

URFD ships 11 real depth frames of fall-01 (camera 0). For each, the depth at the MoveNet
keypoints is sampled from the 16-bit PNG (vigil.depth, as on the robot) and turned into
floor measures by vigil.floor with the Kinect intrinsics. URFD does not publish the camera's
height and pitch, so those two numbers are fitted (least squares) to the official H and D of
the same frames: the figures are how far the keypoint-based measures scatter around the
silhouette-based ones once the mount is right (a lower bound on the shift a robot will see), not
a test on unseen frames.
"""

from __future__ import annotations

import argparse
import json
import os
from pathlib import Path

import numpy as np
from scipy.optimize import least_squares

from backend.labelling.importers.urfd import KINECT_INTRINSICS
from vigil.datasets import urfd
from vigil.depth import read_depth_png, sample_depth
from vigil.floor import CameraMount, floor_measures
from vigil.skeleton import FLOOR_FIELDS

RESULTS = Path(__file__).resolve().parent / "results" / "floor_measures.json"
SEQUENCE = "fall-01"


def paired_frames(directory: Path) -> list[tuple[int, np.ndarray, np.ndarray, np.ndarray]]:
    """(official frame, keypoints, sampled depth, official floor measures) per depth PNG."""
    sequence = urfd.load(directory, [SEQUENCE])[0]
    # The pictures paired with rows as the robot's replay, the importer and training pair them.
    pairs = []
    for i, png in sequence.depth_pictures(directory / urfd.DEPTH_DIR).items():
        if not sequence.detected[i]:
            continue
        frame = int(sequence.image_frame[i])
        depth = sample_depth(read_depth_png(png), sequence.keypoints[i], sequence.depth_scale_mm)
        pairs.append((frame, sequence.keypoints[i], depth, sequence.floor[i]))
    return pairs


def measure(directory: Path) -> dict:
    pairs = paired_frames(directory)

    def predicted(params) -> np.ndarray:
        mount = CameraMount(**KINECT_INTRINSICS, height_m=params[0], pitch_deg=params[1])
        return np.stack([floor_measures(k, d, mount) for _, k, d, _ in pairs])

    official = np.stack([f for *_, f in pairs])
    fit = least_squares(
        lambda p: (predicted(p)[:, :2] - official[:, :2]).ravel(),
        x0=[1.0, 10.0],
        bounds=([0.2, -30.0], [3.0, 60.0]),
    )
    ours = predicted(fit.x)
    diff = ours - official
    return {
        "data": f"REAL: URFD {SEQUENCE}, the {len(pairs)} frames with a depth PNG",
        "frames": [int(f) for f, *_ in pairs],
        "fitted_mount": {
            "height_m": round(float(fit.x[0]), 3),
            "pitch_deg": round(float(fit.x[1]), 2),
        },
        "fields": {
            name: {
                "mean_difference": round(float(diff[:, j].mean()), 3),
                "rms_difference": round(float(np.sqrt((diff[:, j] ** 2).mean())), 3),
                "keypoints": [round(float(v), 3) for v in ours[:, j]],
                "official": [round(float(v), 3) for v in official[:, j]],
            }
            for j, name in enumerate(FLOOR_FIELDS)
        },
        "note": "mount (height, pitch) fitted to the official H and D of these frames; "
        "differences are keypoint-based minus silhouette-based",
        "load_average_1min": os.getloadavg()[0],
    }


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--urfd-dir", type=Path, default=None)
    parser.add_argument("--output", type=Path, default=RESULTS)
    args = parser.parse_args(argv)
    result = measure(Path(args.urfd_dir or urfd.default_dir()))
    args.output.write_text(json.dumps(result, indent=2) + "\n")
    print(json.dumps({k: v for k, v in result.items() if k != "fields"}, indent=2))
    return 0


if __name__ == "__main__":
    raise SystemExit(main())

"""3D view of a frame or clip in viser: keypoints back-projected with depth and intrinsics.

One viser server per backend process, started on first use on `Settings.viser_port`; each
request replaces the scene. viser ships its web client in the wheel: nothing is downloaded.
"""

from __future__ import annotations

import threading
from dataclasses import dataclass

import numpy as np

from backend.labelling.errors import LabellingError
from backend.labelling.rgb import NECK
from vigil.skeleton import BONES

CLIP_FRAMES = 30  # frames with depth shown around the requested one
#: A keypoint's depth pixel can miss the body and hit the wall behind it: readings further than
#: this from the frame's median joint depth are dropped.
MAX_DEPTH_SPREAD_M = 0.8


def robust_depth(depth: np.ndarray) -> np.ndarray:
    depth = depth.astype(np.float64).copy()
    finite = np.isfinite(depth)
    if finite.any():
        median = np.median(depth[finite])
        depth[finite & (np.abs(depth - median) > MAX_DEPTH_SPREAD_M)] = np.nan
    return depth


def back_project(keypoints: np.ndarray, depth: np.ndarray, intrinsics: dict) -> np.ndarray:
    """(25, 3) camera coordinates in metres (x right, y down, z forward); NaN rows where the
    keypoint is missing or has no depth."""
    fx, fy, cx, cy = (float(intrinsics[k]) for k in ("fx", "fy", "cx", "cy"))
    z = depth.astype(np.float64)
    points = np.stack([(keypoints[:, 0] - cx) * z / fx, (keypoints[:, 1] - cy) * z / fy, z], axis=1)
    points[(keypoints[:, 2] <= 0) | ~np.isfinite(z)] = np.nan
    return points


@dataclass(frozen=True, slots=True)
class ViewResult:
    url: str
    frames_shown: list[int]
    centre_frame: int


class Viewer3D:
    def __init__(self, host: str, port: int) -> None:
        self.host, self.port = host, port
        self._server = None
        self._lock = threading.Lock()

    def _ensure_server(self):
        if self._server is None:
            try:
                import viser
            except ImportError as error:
                raise LabellingError("3d: the viser package is not installed") from error
            self._server = viser.ViserServer(host=self.host, port=self.port, verbose=False)
            self._server.scene.set_up_direction("-y")
        return self._server

    def show(
        self,
        name: str,
        indices: np.ndarray,
        keypoints: np.ndarray,
        depth: np.ndarray,
        intrinsics: dict | None,
        frame: int,
    ) -> ViewResult:
        if intrinsics is None:
            raise LabellingError("3d: the video has no camera intrinsics")
        has_depth = np.flatnonzero(np.isfinite(depth).sum(axis=1) >= 3)
        if has_depth.size == 0:
            raise LabellingError("3d: no frame of this video has depth at its keypoints")
        order = np.argsort(np.abs(indices[has_depth] - frame))[:CLIP_FRAMES]
        chosen = np.sort(has_depth[order])
        centre = int(indices[has_depth[order[0]]])
        with self._lock:
            server = self._ensure_server()
            server.scene.reset()
            server.scene.add_frame("/camera", axes_length=0.3, axes_radius=0.01)
            centre_points = None
            for row in chosen:
                index = int(indices[row])
                points = back_project(keypoints[row], robust_depth(depth[row]), intrinsics)
                self._add_skeleton(server, f"/{name}/frame_{index:06d}", points, index == centre)
                if index == centre:
                    centre_points = points
            if centre_points is not None and np.isfinite(centre_points).any():
                target = np.nanmean(centre_points, axis=0)
                server.initial_camera.look_at = tuple(float(v) for v in target)
                server.initial_camera.position = (0.0, -0.3, 0.0)  # at the camera, a bit higher
                server.initial_camera.up = (0.0, -1.0, 0.0)
        return ViewResult(
            f"http://{self.host}:{self.port}", [int(indices[r]) for r in chosen], centre
        )

    @staticmethod
    def _add_skeleton(server, path: str, points: np.ndarray, current: bool) -> None:
        seen = ~np.isnan(points).any(axis=1)
        colour = np.array([220, 38, 38] if current else [100, 116, 139], np.uint8)
        server.scene.add_point_cloud(
            f"{path}/joints",
            points[seen].astype(np.float32),
            np.tile(colour, (int(seen.sum()), 1)),
            point_size=0.04 if current else 0.02,
        )
        bones = [(a, b) for a, b in BONES if seen[a] and seen[b]]
        if bones:
            server.scene.add_line_segments(
                f"{path}/bones",
                np.array([[points[a], points[b]] for a, b in bones], np.float32),
                colour,
                thickness=0.02 if current else 0.008,
            )
        if current and seen[NECK]:
            server.scene.add_label(
                f"{path}/label", path.rsplit("/", 1)[-1], position=tuple(points[NECK])
            )

    def stop(self) -> None:
        with self._lock:
            if self._server is not None:
                self._server.stop()
                self._server = None

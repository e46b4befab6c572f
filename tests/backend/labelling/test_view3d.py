import socket

import httpx
import numpy as np
import pytest
from fastapi.testclient import TestClient

from backend.labelling.viewer3d import back_project, robust_depth
from backend.main import create_app


def test_back_projection_inverts_the_pinhole_camera():
    intrinsics = {"fx": 500.0, "fy": 400.0, "cx": 320.0, "cy": 240.0}
    keypoints = np.zeros((25, 3), np.float32)
    keypoints[0] = (820, 240, 1.0)  # 500 px right of centre at 2 m -> 2 m right
    keypoints[1] = (320, 40, 0.5)  # 200 px above centre at 4 m -> 2 m up (y down)
    keypoints[2] = (100, 100, 0.0)  # missing
    depth = np.full(25, np.nan, np.float32)
    depth[[0, 1, 2]] = (2.0, 4.0, 3.0)
    points = back_project(keypoints, depth, intrinsics)
    assert points[0] == pytest.approx((2.0, 0.0, 2.0))
    assert points[1] == pytest.approx((0.0, -2.0, 4.0))
    assert np.isnan(points[2]).all() and np.isnan(points[3]).all()


def test_depth_readings_off_the_body_are_dropped():
    depth = np.full(25, np.nan)
    depth[:6] = (2.0, 2.1, 2.05, 1.95, 4.5, 2.0)  # 4.5 m: the pixel hit the wall
    cleaned = robust_depth(depth)
    assert np.isnan(cleaned[4]) and np.isfinite(cleaned[[0, 1, 2, 3, 5]]).all()


def _free_port() -> int:
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        return s.getsockname()[1]


def test_view3d_serves_the_nearest_frames_with_depth(settings, urfd_videos, annotator):
    port = _free_port()
    app = create_app(settings.model_copy(update={"viser_port": port}))
    with TestClient(app) as client:
        response = client.post(
            f"/api/labelling/videos/{urfd_videos['fall-01']}/view3d?frame=93",
            headers=annotator.headers,
        )
        assert response.status_code == 200, response.text
        view = response.json()
        assert view["centre_frame"] == 90  # depth pictures exist for 2, 10, ..., 90, 99
        assert sorted(view["frames_shown"]) == [2, 10, 20, 30, 40, 50, 60, 70, 80, 90, 99]
        page = httpx.get(view["url"], timeout=10)
        assert page.status_code == 200 and "<html" in page.text.lower()
        no_depth = client.post(
            f"/api/labelling/videos/{urfd_videos['adl-01']}/view3d?frame=1",
            headers=annotator.headers,
        )
        assert no_depth.status_code == 422 and "depth" in no_depth.json()["detail"]

import cv2
import numpy as np
from sqlalchemy import update

from backend.db import transaction
from backend.models.users import Role
from backend.models.videos import Frame
from tests.backend.labelling.conftest import URFD_DIR

API = "/api/labelling"


def _decode(content: bytes) -> np.ndarray:
    return cv2.imdecode(np.frombuffer(content, np.uint8), cv2.IMREAD_COLOR)


def _clip_frame(number: int) -> np.ndarray:
    capture = cv2.VideoCapture(str(URFD_DIR / "video" / "fall-01-cam0.mp4"))
    for _ in range(number + 1):
        ok, picture = capture.read()
    capture.release()
    return picture[:, 320:]


def test_rgb_frame_is_the_exact_clip_frame(client, urfd_videos, annotator):
    video = urfd_videos["fall-01"]
    for frame in (50, 120):
        response = client.get(
            f"{API}/videos/{video}/rgb/{frame}?blur=false", headers=annotator.headers
        )
        assert response.headers["content-type"] == "image/jpeg"
        picture = _decode(response.content)
        assert picture.shape == (240, 320, 3)
        errors = [
            np.abs(picture.astype(int) - _clip_frame(n).astype(int)).mean()
            for n in (frame - 2, frame - 1, frame)
        ]
        assert int(np.argmin(errors)) == 1, errors  # skeleton frame i shows clip frame i - 1


def test_head_is_blurred_by_default_and_only_annotators_may_unblur(
    client, urfd_videos, annotator, make_account
):
    video = urfd_videos["fall-01"]
    blurred = _decode(client.get(f"{API}/videos/{video}/rgb/30", headers=annotator.headers).content)
    sharp = _decode(
        client.get(f"{API}/videos/{video}/rgb/30?blur=false", headers=annotator.headers).content
    )
    changed = np.abs(blurred.astype(int) - sharp.astype(int)).sum(axis=2) > 30
    assert 0.002 < changed.mean() < 0.3  # a head-sized region, not the whole picture
    engineer = make_account(Role.ENGINEER, None, "eve")
    assert client.get(f"{API}/videos/{video}/rgb/30", headers=engineer.headers).status_code == 200
    refused = client.get(f"{API}/videos/{video}/rgb/30?blur=false", headers=engineer.headers)
    assert refused.status_code == 403
    assert client.get(f"{API}/videos/{video}/rgb/160", headers=annotator.headers).status_code == 422
    no_clip = client.get(f"{API}/videos/{urfd_videos['adl-01']}/rgb/3", headers=annotator.headers)
    assert no_clip.status_code == 404


def test_probability_lane_from_stored_scores_suggests_the_fall(
    client, urfd_videos, session_factory, annotator
):
    video = urfd_videos["fall-01"]
    with transaction(session_factory) as session:
        for lo, hi, p in ((0, 99, 0.1), (100, 159, 0.9)):
            session.execute(
                update(Frame)
                .where(Frame.video_id == video, Frame.index.between(lo, hi))
                .values(
                    scores={"normal": 1 - p, "emergency": p}, threshold=0.5, model_version="m-1"
                )
            )
    lane = client.get(f"{API}/videos/{video}/probability", headers=annotator.headers).json()
    assert lane["source"] == "stored" and lane["model_version"] == "m-1"
    assert lane["probability"][99] == 0.1 and lane["probability"][100] == 0.9
    assert lane["suggestions"] == [{"first_frame": 100, "last_frame": 159, "label_key": "falling"}]

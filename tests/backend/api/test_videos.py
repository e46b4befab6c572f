"""GET /api/videos/{id}/frames (the labelling timeline) is encoded without a model per frame:
the same JSON as list[FrameOut] of the frames decoded one by one."""

from __future__ import annotations

from pydantic import TypeAdapter
from sqlalchemy import select

from backend.api.videos import FrameOut
from backend.db import transaction
from backend.models import Frame, Role
from tests.backend.storage import factories as f
from vigil.skeleton import decode_keypoints, depth_to_json, floor_to_json


def test_timeline_json_is_what_the_response_model_gives(client, make_account, session_factory):
    engineer = make_account(Role.ENGINEER, ward=None, username="eng")
    with transaction(session_factory) as session:
        video = f.robot_video(session, "r1-t", "r1", [f.NOW + i / 10 for i in range(12)])
        row = session.scalars(select(Frame).where(Frame.index == 4)).one()
        row.floor, row.shadow_decision, row.scores = None, "emergency", None
        video_id = video.id
    response = client.get(f"/api/videos/{video_id}/frames?start=2&end=8", headers=engineer.headers)
    with session_factory() as session:
        frames = session.scalars(
            select(Frame).where(Frame.index.between(2, 8)).order_by(Frame.index)
        ).all()
        expected = [
            FrameOut(
                index=x.index,
                ts=x.ts,
                seq=x.seq,
                keypoints=decode_keypoints(x.keypoints).tolist(),
                depth=depth_to_json(x.depth),
                floor=floor_to_json(x.floor),
                decision=x.decision,
                scores=x.scores,
                model_version=x.model_version,
                threshold=x.threshold,
                delay_ms=x.delay_ms,
                shadow_decision=x.shadow_decision,
                shadow_model_version=x.shadow_model_version,
            )
            for x in frames
        ]
    adapter = TypeAdapter(list[FrameOut])
    assert response.status_code == 200
    assert response.headers["content-type"] == "application/json"
    assert response.json() == adapter.dump_python(expected, mode="json")
    assert adapter.validate_json(response.content) == expected
    assert [x["index"] for x in response.json()] == list(range(2, 9))
    assert any(x.depth is None for x in frames) and any(x.depth is not None for x in frames)

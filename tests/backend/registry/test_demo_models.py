"""`make run`'s registry: both walking models registered with their gold evaluation, and every
robot given a model it can feed through the rollout service (worker.bootstrap)."""

from __future__ import annotations

from sqlalchemy import select, update

from backend.db import transaction
from backend.models import Deployment, ModelVersion, Robot, Role
from backend.models.videos import Frame, Video
from backend.registry.capability import fallback_model
from tests.backend.registry.conftest import FEEDS_ALL
from tests.registry_fixtures import GOLD, TRAIN
from worker.bootstrap import add_floor_measures, promote_demo_models, register_model_dir


def test_every_robot_gets_a_model_it_can_feed_and_walking_keeps_its_fallback(
    client,
    make_account,
    fleet,
    urfd_db,
    factory,
    settings,
    trained_model_dir,
    keypoints_model_dir,
    tmp_path,
):
    make_account(Role.ENGINEER, username="engineer")  # the demo's signer
    store = tmp_path / "store"
    with transaction(factory) as session:
        # The import stores URFD's floor measures; the backfill (for older databases) finds
        # nothing to fill.
        assert add_floor_measures(session, TRAIN + GOLD) == 0
        older = session.scalars(select(Video).where(Video.name == "fall-07")).one()
        session.execute(update(Frame).where(Frame.video_id == older.id).values(floor=None))
        assert add_floor_measures(session, TRAIN + GOLD) == 1  # a database from before
        for robot in session.scalars(select(Robot)):
            robot.inputs = None  # no robot said hello yet: keypoints only
        floor = register_model_dir(session, trained_model_dir, store)
        keypoints = register_model_dir(session, keypoints_model_dir, store)
        assert register_model_dir(session, keypoints_model_dir, store).id == keypoints.id
        assert floor.metrics["gold"]["falls_detected"] == floor.metrics["gold"]["falls_total"]
        first = promote_demo_models(session, floor, keypoints, settings)
    assert first[-1] == "rf-test-1 stays a candidate: no robot said it feeds keypoints, floor"
    with factory() as session:
        assigned = {r.id: r.assigned_model_id for r in session.scalars(select(Robot))}
        assert set(assigned.values()) == {keypoints.id}
        assert fallback_model(session, "walking").id == keypoints.id
        video = session.scalars(select(Video).where(Video.name == "fall-07")).one()
        assert session.scalars(
            select(Frame.floor).where(Frame.video_id == video.id, Frame.floor.is_not(None))
        ).first()

    # Their hellos: robot-a and robot-b feed floor measures, the others keypoints only.
    with transaction(factory) as session:
        for robot_id in ("robot-a", "robot-b"):
            session.get(Robot, robot_id).inputs = FEEDS_ALL
        floor, keypoints = (session.get(ModelVersion, m.id) for m in (floor, keypoints))
        second = promote_demo_models(session, floor, keypoints, settings)
    assert second == [
        "promoted rf-test-1 to robot-a (active)",
        "promoted rf-test-1 to robot-b (active)",
    ]
    with factory() as session:
        assigned = {r.id: r.assigned_model_id for r in session.scalars(select(Robot))}
        assert assigned == {
            "robot-a": floor.id,
            "robot-b": floor.id,
            "robot-c": keypoints.id,
            "robot-d": keypoints.id,
        }
        assert session.get(ModelVersion, keypoints.id).status == "production"
        deployments = session.scalars(select(Deployment)).all()
        assert {d.scope for d in deployments} == {"robot"} and len(deployments) == 6
        floor, keypoints = (session.get(ModelVersion, m.id) for m in (floor, keypoints))
    with transaction(factory) as session:
        assert promote_demo_models(session, floor, keypoints, settings) == []  # nothing to do

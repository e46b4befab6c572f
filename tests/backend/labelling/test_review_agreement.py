import pytest
from sqlalchemy import update

from backend.db import transaction
from backend.labelling.agreement import cohen_kappa
from backend.models.alarms import Alarm, AlarmKind, AlarmPriority, AlarmState, Verdict
from backend.models.annotations import AnnotationSegment, SegmentSource, SegmentStatus
from backend.models.robots import Robot
from backend.models.videos import Frame

API = "/api/labelling"


def _segment(session, video_id, first, last, label, source, **extra):
    segment = AnnotationSegment(
        video_id=video_id,
        first_frame=first,
        last_frame=last,
        label_key=label,
        taxonomy_version=1,
        status=SegmentStatus.PENDING,
        source=source,
        **extra,
    )
    session.add(segment)
    session.flush()
    return segment.id


def test_queue_puts_nurse_rejected_alarms_first_then_model_disagreements(
    client, urfd_videos, session_factory, annotator, annotator2
):
    fall, adl = urfd_videos["fall-01"], urfd_videos["adl-01"]
    # An annotator's own submitted segment, where the stored model decision disagrees.
    plain = client.post(
        f"{API}/videos/{adl}/segments",
        headers=annotator.headers,
        json={"first_frame": 0, "last_frame": 9, "label_key": "walking"},
    ).json()
    disagreeing = client.post(
        f"{API}/videos/{fall}/segments",
        headers=annotator.headers,
        json={"first_frame": 0, "last_frame": 9, "label_key": "walking"},
    ).json()
    for video in (adl, fall):
        client.post(f"{API}/videos/{video}/submit", headers=annotator.headers)
    with transaction(session_factory) as session:
        session.execute(
            update(Frame)
            .where(Frame.video_id == fall, Frame.index < 10)
            .values(decision="emergency")
        )
        session.add(Robot(id="r-1", ward="w"))
        session.flush()
        alarms = []
        for verdict in (Verdict.TRUE_EMERGENCY, Verdict.FALSE_ALARM):
            alarm = Alarm(
                kind=AlarmKind.EMERGENCY,
                priority=AlarmPriority.HIGH,
                robot_id="r-1",
                ward="w",
                state=AlarmState.RESOLVED,
                verdict=verdict,
            )
            session.add(alarm)
            session.flush()
            alarms.append(alarm.id)
        true_alarm = _segment(
            session,
            fall,
            90,
            120,
            "falling",
            SegmentSource.NURSE_VERDICT,
            alarm_id=alarms[0],
            priority=10,
        )
        false_alarm = _segment(
            session,
            adl,
            40,
            60,
            "bending",
            SegmentSource.NURSE_VERDICT,
            alarm_id=alarms[1],
            priority=100,
        )
        shadow = _segment(session, adl, 70, 80, "walking", SegmentSource.SHADOW_DISAGREEMENT)
    queue = client.get(f"{API}/review-queue", headers=annotator2.headers).json()
    order = [item["segment"]["id"] for item in queue]
    assert order[0] == false_alarm
    assert set(order[1:3]) == {shadow, disagreeing["id"]}
    assert set(order[3:]) == {true_alarm, plain["id"]}
    assert queue[0]["reason"] == "nurse rejected the alarm as false"


def test_cohen_kappa_matches_hand_computation():
    import numpy as np

    a = np.array(["x", "x", "y", "y", "y", "x"])
    b = np.array(["x", "y", "y", "y", "x", "x"])
    # observed 4/6; expected (3/6*3/6 + 3/6*3/6) = 0.5 -> kappa = (2/3 - 1/2) / (1/2) = 1/3
    assert cohen_kappa(a, b) == pytest.approx(1 / 3)
    assert cohen_kappa(a, a) == pytest.approx(1.0)


def test_agreement_of_two_annotators_on_one_video(client, urfd_videos, annotator, annotator2):
    video = urfd_videos["fall-01"]
    for account, falling_from in ((annotator, 100), (annotator2, 103)):
        for first, last, label in (
            (0, falling_from - 1, "walking"),
            (falling_from, 119, "falling"),
            (120, 159, "lying_on_floor"),
        ):
            response = client.post(
                f"{API}/videos/{video}/segments",
                headers=account.headers,
                json={"first_frame": first, "last_frame": last, "label_key": label},
            )
            assert response.status_code == 201
    names = client.get(f"{API}/videos/{video}/annotators", headers=annotator.headers).json()
    assert names["annotators"] == ["anna", "bert", "(imported)"]
    result = client.get(
        f"{API}/videos/{video}/agreement?a=anna&b=bert", headers=annotator.headers
    ).json()
    assert result["frames_compared"] == 160
    stages = {s["label_key"]: s for s in result["stages"]}
    assert stages["falling"]["onset_diff_ms"] == pytest.approx(3 * 1000 / 30)
    assert stages["falling"]["offset_diff_ms"] == pytest.approx(0.0)
    assert stages["lying_on_floor"]["onset_diff_ms"] == pytest.approx(0.0)
    kappas = {x["label_key"]: x["kappa"] for x in result["labels"]}
    assert kappas["lying_on_floor"] == pytest.approx(1.0)
    assert 0.5 < kappas["falling"] < 1.0
    missing = client.get(
        f"{API}/videos/{video}/agreement?a=anna&b=nobody", headers=annotator.headers
    )
    assert missing.status_code == 404


def test_agreement_of_an_annotator_with_the_imported_labels(client, urfd_videos, annotator):
    video = urfd_videos["fall-01"]
    listed = client.get(f"{API}/videos/{video}/segments", headers=annotator.headers).json()
    imported = [
        (s["first_frame"], s["last_frame"], s["label_key"])
        for s in listed
        if s["source"] == "import"
    ]
    assert [label for *_, label in sorted(imported)] == ["walking", "falling", "lying_on_floor"]
    for first, last, label in imported:
        response = client.post(
            f"{API}/videos/{video}/segments",
            headers=annotator.headers,
            json={"first_frame": first + 2, "last_frame": last, "label_key": label}
            if label == "falling"
            else {"first_frame": first, "last_frame": last, "label_key": label},
        )
        assert response.status_code == 201, response.text
    result = client.get(
        f"{API}/videos/{video}/agreement",
        params={"a": "(imported)", "b": "anna"},
        headers=annotator.headers,
    )
    assert result.status_code == 200, result.text
    timing = {s["label_key"]: s for s in result.json()["stages"]}
    assert timing["falling"]["onset_diff_ms"] == pytest.approx(2 * 1000 / 30, abs=1)

from sqlalchemy import select

from backend.alarm_review.feedback import (
    alarm_frame_span,
    placeholder_name,
    propose_label_from_verdict,
    proposed_label,
    review_queue,
)
from backend.models import AnnotationSegment, SegmentEvent, Verdict
from backend.models.alarms import FalseAlarmReason

from .factories import alarm, robot_with_frames


def test_proposed_label_names_a_fine_label_only_when_the_reason_does():
    assert proposed_label(Verdict.FALSE_ALARM, FalseAlarmReason.BENDING) == "bending"
    assert (
        proposed_label(Verdict.FALSE_ALARM, FalseAlarmReason.OTHER) == "verdict:false_alarm:other"
    )
    assert proposed_label(Verdict.TRUE_EMERGENCY, None) == "verdict:true_emergency"


def test_a_verdict_placeholder_reads_as_words_not_as_its_key():
    assert (
        placeholder_name(proposed_label(Verdict.TRUE_EMERGENCY, None))
        == "Nurse verdict: true emergency; choose the fine label"
    )
    assert (
        placeholder_name(proposed_label(Verdict.FALSE_ALARM, FalseAlarmReason.OTHER))
        == "Nurse verdict: false alarm (other); choose the fine label"
    )
    assert placeholder_name("bending") is None


def test_verdict_becomes_pending_segment_on_exact_span(session):
    video = robot_with_frames(session)
    row = alarm(
        session,
        video,
        state="resolved",
        verdict="false_alarm",
        reason="sitting_down",
        comment="sat on the bench",
    )
    assert alarm_frame_span(session, row) == (53, 69)

    segment = propose_label_from_verdict(session, row, actor_id=None)
    session.commit()

    stored = session.scalars(select(AnnotationSegment)).one()
    assert stored.id == segment.id
    assert (stored.video_id, stored.first_frame, stored.last_frame) == (video.id, 53, 69)
    assert stored.label_key == "sitting_down"
    assert stored.status == "pending" and stored.source == "nurse_verdict"
    assert stored.model_version == "m1" and stored.alarm_id == row.id
    assert stored.review_comment == "sat on the bench"
    event = session.scalars(select(SegmentEvent)).one()
    assert event.snapshot["verdict"] == "false_alarm"
    # A second call does not duplicate the label.
    assert propose_label_from_verdict(session, row, actor_id=None).id == segment.id
    assert len(session.scalars(select(AnnotationSegment)).all()) == 1


def test_no_segment_without_frames_or_for_technical_alarms(session):
    video = robot_with_frames(session)
    technical = alarm(
        session, video, kind="robot_offline", transport_key="", verdict="unsure", state="resolved"
    )
    assert propose_label_from_verdict(session, technical, actor_id=None) is None
    no_frames = alarm(
        session,
        video,
        first_seq=5000,
        last_seq=5010,
        verdict="unsure",
        state="resolved",
        kind="pause",
    )
    assert propose_label_from_verdict(session, no_frames, actor_id=None) is None
    unresolved = alarm(session, video, kind="pause", transport_key="x")
    assert propose_label_from_verdict(session, unresolved, actor_id=None) is None


def test_review_queue_puts_nurse_rejected_alarms_first(session):
    video = robot_with_frames(session)
    verdicts = ["true_emergency", "unsure", "false_alarm"]
    ids = {}
    for i, verdict in enumerate(verdicts):
        row = alarm(session, video, state="resolved", verdict=verdict, transport_key=f"k{i}")
        ids[verdict] = propose_label_from_verdict(session, row, actor_id=None).id
    session.commit()
    assert [s.id for s in review_queue(session)] == [
        ids["false_alarm"],
        ids["unsure"],
        ids["true_emergency"],
    ]

import numpy as np
from sqlalchemy import select

from backend.db import transaction
from backend.labelling.importers.urfd import import_urfd
from backend.models.annotations import AnnotationSegment, SegmentSource, SegmentStatus
from backend.models.videos import Frame, Split, Video
from tests.backend.labelling.conftest import URFD_DIR
from vigil.datasets import urfd
from vigil.skeleton import decode_depth


def test_fall_video_carries_official_labels_as_accepted_segments(urfd_videos, session_factory):
    sequence = urfd.load(URFD_DIR, ["fall-01"])[0]
    with session_factory() as session:
        video = session.get(Video, urfd_videos["fall-01"])
        assert video.frame_count == len(sequence) == 160
        assert video.rgb_path.endswith("fall-01-cam0.mp4") and video.rgb_crop["x"] == 320
        assert video.split == Split.TRAIN and video.mode == "walking"
        segments = session.scalars(
            select(AnnotationSegment)
            .where(AnnotationSegment.video_id == video.id)
            .order_by(AnnotationSegment.first_frame)
        ).all()
    assert [s.label_key for s in segments] == ["walking", "falling", "lying_on_floor"]
    assert all(
        s.status == SegmentStatus.ACCEPTED and s.source == SegmentSource.IMPORT for s in segments
    )
    expected = {-1: "walking", 0: "falling", 1: "lying_on_floor"}
    for s in segments:
        labels = sequence.urfd_label[s.first_frame : s.last_frame + 1]
        assert {expected[int(v)] for v in labels} == {s.label_key}
    assert segments[0].first_frame == 0 and segments[-1].last_frame == 159


def test_adl_lying_is_deliberate_and_unlabelled_frames_get_no_segment(urfd_videos, session_factory):
    sequence = urfd.load(URFD_DIR, ["adl-01"])[0]
    with session_factory() as session:
        segments = session.scalars(
            select(AnnotationSegment).where(AnnotationSegment.video_id == urfd_videos["adl-01"])
        ).all()
    covered = {i for s in segments for i in range(s.first_frame, s.last_frame + 1)}
    assert covered == set(np.flatnonzero(~np.isnan(sequence.urfd_label)).tolist())
    assert "lying_on_floor" not in {s.label_key for s in segments}
    assert {s.label_key for s in segments} <= {"walking", "bending", "lying_down_deliberately"}


def test_depth_pictures_give_depth_at_keypoints(urfd_videos, session_factory):
    with session_factory() as session:
        rows = dict(
            session.execute(
                select(Frame.index, Frame.depth).where(Frame.video_id == urfd_videos["fall-01"])
            ).all()
        )
    with_depth = sorted(i for i, blob in rows.items() if blob is not None)
    assert with_depth == [2, 10, 20, 30, 40, 50, 60, 70, 80, 90, 99]
    metres = decode_depth(rows[10])
    seen = metres[~np.isnan(metres)]
    assert seen.size >= 5 and np.all((seen > 0.5) & (seen < 6.0))
    with session_factory() as session:
        assert session.get(Video, urfd_videos["fall-01"]).depth_path is not None
        assert session.get(Video, urfd_videos["adl-01"]).depth_path is None  # no pictures


def test_import_is_idempotent(urfd_videos, session_factory):
    with transaction(session_factory) as session:
        report = import_urfd(session, URFD_DIR, ["fall-01", "adl-01"])
    assert report.created == [] and sorted(report.skipped) == ["adl-01", "fall-01"]
    with session_factory() as session:
        assert session.query(AnnotationSegment).count() == report.segments + 3 + len(
            session.scalars(
                select(AnnotationSegment).where(AnnotationSegment.video_id == urfd_videos["adl-01"])
            ).all()
        )


def test_imported_depth_is_the_robots_depth_on_fall_01s_real_pictures(urfd_videos, session_factory):
    """Train equals serve (issue #34): on fall-01's 11 real depth pictures the depth the importer
    stores at each keypoint is the depth the robot's frame path computes from the same picture
    (its replay source pairs pictures with rows, its detector samples them): 0 differing."""
    from robot_agent.sources.replay import UrfdReplaySource
    from vigil.depth import sample_depth
    from vigil.detector import PatientFrames

    with session_factory() as session:
        stored = dict(
            session.execute(
                select(Frame.index, Frame.depth).where(Frame.video_id == urfd_videos["fall-01"])
            ).all()
        )
    robot = PatientFrames()  # as robot_agent.pipeline builds it
    assert robot.depth_sampler is sample_depth
    source = UrfdReplaySource("fall-01", URFD_DIR, speed=0, depth_dir=URFD_DIR / "depth")
    compared = differing = 0
    rows_with_pictures = []
    for observation in source:
        frame, seen = robot(observation)
        if observation.depth_image is None:
            continue
        rows_with_pictures.append(observation.index)
        assert seen
        imported = decode_depth(stored[observation.index])
        present = frame.keypoints[:, 2] > 0
        compared += int(present.sum())
        differing += int(
            (~np.isclose(imported, frame.depth, rtol=0, atol=1e-6, equal_nan=True)).sum()
        )
    assert rows_with_pictures == [2, 10, 20, 30, 40, 50, 60, 70, 80, 90, 99]
    assert compared == 165
    assert differing == 0

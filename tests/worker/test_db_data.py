"""Per-frame labels from segments have one rule (issue #34): the CSV export and the training rows
agree row by row, overlapping segments included (the segment updated last wins the frame)."""

from __future__ import annotations

import csv
import io
from datetime import timedelta

from sqlalchemy import select

from backend.db import transaction
from backend.labelling.export import export_csv
from backend.labelling.importers.urfd import import_urfd
from backend.labelling.segments import SegmentDraft, create_segment
from backend.models.annotations import AnnotationSegment, SegmentSource
from backend.models.videos import Video
from vigil.classes import MODE_CLASSES, TransportMode
from vigil.datasets import urfd
from worker.db_data import frame_data

WALKING = TransportMode.WALKING


def exported_and_trained(session, video: Video) -> tuple[list[str], list[str]]:
    rows = list(csv.DictReader(io.StringIO(export_csv(session, video))))
    data = frame_data(session, [video], WALKING)
    classes = MODE_CLASSES[WALKING]
    trained = [classes[t].value if t >= 0 else "" for t in data.target]
    return [row["walking"] for row in rows], trained


def test_export_and_training_labels_agree_row_by_row_with_overlapping_segments(factory):
    with transaction(factory) as session:
        import_urfd(session, urfd.default_dir(), ["adl-01"])
    with transaction(factory) as session:
        video = session.scalars(select(Video).where(Video.name == "adl-01")).one()
        exported, trained = exported_and_trained(session, video)
        assert len(exported) == len(trained) == video.frame_count
        assert exported == trained  # no overlap yet: the imported runs
        first, second, *_ = session.scalars(
            select(AnnotationSegment)
            .where(AnnotationSegment.video_id == video.id)
            .order_by(AnnotationSegment.first_frame)
        ).all()
        assert first.label_key == "walking"
        assert set(exported[: second.first_frame + 11]) <= {"normal", ""}
        end = second.first_frame + 10
        # A new segment (the highest id) over the walking run and into the next, labelled
        # Emergency; the walking run (a lower id) is then updated last.
        overlap = create_segment(
            session,
            video,
            SegmentDraft(first.first_frame, end, "lying_on_floor"),
            None,
            source=SegmentSource.IMPORT,
            entry="import",
        )
        session.flush()
        first.updated_at = overlap.updated_at + timedelta(minutes=5)
        walking = (first.first_frame, first.last_frame)
    with factory() as session:
        video = session.scalars(select(Video).where(Video.name == "adl-01")).one()
        exported, trained = exported_and_trained(session, video)
    assert exported == trained  # row by row
    # By the rule the walking run, updated last, keeps its frames (Normal); past it the new
    # segment wins over the older runs (Emergency).
    assert set(exported[walking[0] : walking[1] + 1]) == {"normal"}
    assert set(exported[walking[1] + 1 : end + 1]) == {"emergency"}

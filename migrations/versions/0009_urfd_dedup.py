"""Merge the duplicated URFD recordings: one video per sequence, fine labels by the one map.

Until now `make run` imported URFD twice: `seed-demo` as `fall-01` (the labelling importer) and
the worker's bootstrap as `urfd/fall-01` (with another fine-label map: `standing` for a fall's
"-1", `sitting_down` for an ADL's "0"). First the copy's import segments are relabelled by the
one map (docs/labelling.md, `vigil.datasets.urfd.FINE_LABELS`). Then, for each sequence:

- both copies: the `fall-01` video is kept. Every segment of the copy a person touched (an
  annotator, a reviewer or any event with an actor, and every segment not from the import)
  moves to it, as do alarms; the copy's floor measures fill the kept frames that have none; a
  split changed on the copy (the kept video still on the default split) is taken over. Then
  the copy's machine-made import segments (the same official labels), its frames (the same
  keypoints) and the copy itself are deleted.
- only `urfd/fall-01`: it is renamed `fall-01`.

Job parameters naming a copy's id (`video_ids`) name the kept video, and recording names in
model lineage and metrics, job results and gate reports lose the `urfd/` prefix, so the gate's
"gold recordings were also training data" check still compares like with like.

Downgrade changes nothing: the merged rows are valid under the previous schema, and the
duplicate they replace held nothing the kept video does not.

Revision ID: 0009_urfd_dedup
Revises: 0008_sessions
"""

from collections.abc import Sequence

import sqlalchemy as sa
from alembic import op

revision: str = "0009_urfd_dedup"
down_revision: str | None = "0008_sessions"
branch_labels: str | Sequence[str] | None = None
depends_on: str | Sequence[str] | None = None

# Frozen copies (a migration must not change when the code does).
NAMES = [f"fall-{i:02d}" for i in range(1, 31)] + [f"adl-{i:02d}" for i in range(1, 41)]
PREFIX = "urfd/"
#: The worker importer's labels -> the one map's, by sequence kind (the others agreed).
RELABEL = {"fall": {"standing": "walking"}, "adl": {"sitting_down": "bending"}}

videos = sa.table(
    "videos",
    sa.column("id", sa.Integer),
    sa.column("name", sa.String),
    sa.column("source", sa.String),
    sa.column("split", sa.String),
)
segments = sa.table(
    "annotation_segments",
    sa.column("id", sa.Integer),
    sa.column("video_id", sa.Integer),
    sa.column("label_key", sa.String),
    sa.column("source", sa.String),
    sa.column("annotator_id", sa.Integer),
    sa.column("reviewer_id", sa.Integer),
)
events = sa.table(
    "segment_events",
    sa.column("segment_id", sa.Integer),
    sa.column("actor_id", sa.Integer),
)
frames = sa.table("frames", sa.column("video_id", sa.Integer))
alarms = sa.table("alarms", sa.column("id", sa.Integer), sa.column("video_id", sa.Integer))
jobs = sa.table(
    "jobs", sa.column("id", sa.Integer), sa.column("params", sa.JSON), sa.column("result", sa.JSON)
)
model_versions = sa.table(
    "model_versions",
    sa.column("id", sa.Integer),
    sa.column("lineage", sa.JSON),
    sa.column("metrics", sa.JSON),
)
deployments = sa.table(
    "deployments", sa.column("id", sa.Integer), sa.column("gate_report", sa.JSON)
)


def default_split(name: str) -> str:
    return "test" if int(name.split("-")[1]) % 5 == 0 else "train"


def _machine_made(connection, video_id: int) -> list[int]:
    """Import segments of the video nobody touched (no annotator, reviewer or actor)."""
    touched = sa.select(events.c.segment_id).where(events.c.actor_id.is_not(None))
    return list(
        connection.scalars(
            sa.select(segments.c.id).where(
                segments.c.video_id == video_id,
                segments.c.source == "import",
                segments.c.annotator_id.is_(None),
                segments.c.reviewer_id.is_(None),
                segments.c.id.not_in(touched),
            )
        )
    )


def _renamed(value):
    """`value` with every string "urfd/<sequence>" replaced by "<sequence>" (JSON documents)."""
    if isinstance(value, str):
        return value.removeprefix(PREFIX) if value.removeprefix(PREFIX) in NAMES else value
    if isinstance(value, list):
        return [_renamed(v) for v in value]
    if isinstance(value, dict):
        return {k: _renamed(v) for k, v in value.items()}
    return value


def _relabel(connection, name: str, copy_id: int) -> None:
    for old, new in RELABEL[name.split("-")[0]].items():
        connection.execute(
            segments.update()
            .where(
                segments.c.video_id == copy_id,
                segments.c.source == "import",
                segments.c.label_key == old,
            )
            .values(label_key=new)
        )


def _merge(connection, name: str, copy: dict, kept: dict) -> None:
    copy_id, kept_id = copy["id"], kept["id"]
    machine_made = _machine_made(connection, copy_id)
    if machine_made:
        connection.execute(events.delete().where(events.c.segment_id.in_(machine_made)))
        connection.execute(segments.delete().where(segments.c.id.in_(machine_made)))
    connection.execute(
        segments.update().where(segments.c.video_id == copy_id).values(video_id=kept_id)
    )
    connection.execute(alarms.update().where(alarms.c.video_id == copy_id).values(video_id=kept_id))
    connection.execute(
        sa.text(
            "UPDATE frames SET floor = (SELECT c.floor FROM frames AS c WHERE c.video_id = :copy "
            'AND c."index" = frames."index") WHERE frames.video_id = :kept AND frames.floor IS NULL'
        ),
        {"copy": copy_id, "kept": kept_id},
    )
    default = default_split(name)
    if kept["split"] == default and copy["split"] != default:
        connection.execute(
            videos.update().where(videos.c.id == kept_id).values(split=copy["split"])
        )
    connection.execute(frames.delete().where(frames.c.video_id == copy_id))
    connection.execute(videos.delete().where(videos.c.id == copy_id))


def _rename(connection, name: str, copy: dict) -> None:
    connection.execute(videos.update().where(videos.c.id == copy["id"]).values(name=name))


def _rewrite_json(connection, table, columns, merged: dict[int, int]) -> None:
    for row in connection.execute(sa.select(table.c.id, *(table.c[c] for c in columns))).all():
        values = {}
        for column in columns:
            document = row._mapping[column]
            changed = _renamed(document)
            if column == "params" and isinstance(changed, dict) and changed.get("video_ids"):
                changed = {**changed, "video_ids": [merged.get(i, i) for i in changed["video_ids"]]}
            if changed != document:
                values[column] = changed
        if values:
            connection.execute(table.update().where(table.c.id == row.id).values(**values))


def upgrade() -> None:
    connection = op.get_bind()
    rows = connection.execute(
        sa.select(videos.c.id, videos.c.name, videos.c.split).where(
            videos.c.source == "urfd",
            videos.c.name.in_(NAMES + [PREFIX + n for n in NAMES]),
        )
    ).all()
    by_name = {row.name: dict(row._mapping) for row in rows}
    if not any(PREFIX + name in by_name for name in NAMES):
        return  # imported once (a fresh database, or one made without the worker's import)
    merged: dict[int, int] = {}
    for name in NAMES:
        copy = by_name.get(PREFIX + name)
        if copy is None:
            continue
        _relabel(connection, name, copy["id"])
        kept = by_name.get(name)
        if kept is None:
            _rename(connection, name, copy)
        else:
            _merge(connection, name, copy, kept)
            merged[copy["id"]] = kept["id"]
    _rewrite_json(connection, jobs, ["params", "result"], merged)
    _rewrite_json(connection, model_versions, ["lineage", "metrics"], merged)
    _rewrite_json(connection, deployments, ["gate_report"], merged)


def downgrade() -> None:
    """Nothing to undo in the schema; the merged recordings stay merged."""

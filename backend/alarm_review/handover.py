"""Shift handover: one view of a shift for the nurse who takes over (what clinical alarm systems
call a response report).

Which alarms: every alarm still unresolved now, whenever it was raised, and every alarm raised
during the shift. Sections: open (not acknowledged), missed (the escalation chain ended without
an acknowledgement: "missed: needs review"), acknowledged but unresolved, resolved. An alarm
that escalated keeps its section and is counted as escalated too; one that was missed and is
resolved since counts as missed.

Fatigue figures cover the alarms raised during the shift: how many, the non-actionable share
(verdict "false alarm" among the alarms resolved with a verdict) and the time to acknowledge as
percentiles, counting an alarm nobody acknowledged at the time it went without (until resolved
or until the end of the period), as `backend.alarm_review.fatigue` does.
"""

from __future__ import annotations

import csv
import io
import math
from collections import Counter, defaultdict
from collections.abc import Collection, Iterable, Sequence
from datetime import datetime

from backend.alarm_review.fatigue import ack_wait_s, was_missed
from backend.models.alarms import TECHNICAL_KINDS, Alarm, AlarmKind, AlarmState, Verdict

SECTIONS = ("open", "missed", "acknowledged", "resolved")


def section_of(alarm: Alarm) -> str:
    return AlarmState(alarm.state).value


def percentile(values: Sequence[float], q: float) -> float | None:
    """Nearest-rank percentile (q in 0..100); None for no values."""
    if not values:
        return None
    ordered = sorted(values)
    rank = max(1, math.ceil(q / 100 * len(ordered)))
    return round(ordered[rank - 1], 1)


def fatigue_figures(alarms: Iterable[Alarm], missed_ids: Collection[int], until: datetime) -> dict:
    alarms = list(alarms)
    with_verdict = [a for a in alarms if a.verdict is not None]
    false_alarms = sum(a.verdict == Verdict.FALSE_ALARM for a in with_verdict)
    waits = [ack_wait_s(a, until) for a in alarms]
    return {
        "alarms": len(alarms),
        "emergencies": sum(a.kind == AlarmKind.EMERGENCY for a in alarms),
        "pauses": sum(a.kind == AlarmKind.PAUSE for a in alarms),
        "technical": sum(a.kind in TECHNICAL_KINDS for a in alarms),
        "resolved_with_verdict": len(with_verdict),
        "non_actionable": false_alarms,
        "non_actionable_share": round(false_alarms / len(with_verdict), 4)
        if with_verdict
        else None,
        "acknowledged": sum(a.acknowledged_at is not None for a in alarms),
        "unacknowledged": sum(a.acknowledged_at is None for a in alarms),
        "escalated": sum(a.escalation_level > 0 for a in alarms),
        "missed": sum(was_missed(a, missed_ids) for a in alarms),
        "ack_p50_s": percentile(waits, 50),
        "ack_p90_s": percentile(waits, 90),
        "ack_p95_s": percentile(waits, 95),
    }


def _robot_order(item: tuple[str | None, Counter]) -> tuple[bool, str]:
    """Robots by id; the ward system's own alarms (no robot) last."""
    robot_id = item[0]
    return robot_id is None, robot_id or ""


def handover(
    alarms: Iterable[Alarm],
    missed_ids: Collection[int],
    since: datetime,
    until: datetime,
) -> dict:
    """The handover's figures and rows (alarms newest first); `until` bounds the waits."""
    alarms = sorted(alarms, key=lambda a: (a.raised_at, a.id), reverse=True)
    in_shift = [a for a in alarms if since <= a.raised_at < until]
    sections = Counter(section_of(a) for a in alarms)
    per_robot: dict[str | None, Counter] = defaultdict(Counter)
    for alarm in alarms:
        row = per_robot[alarm.robot_id]
        row["alarms"] += 1
        row[section_of(alarm)] += 1
        row["escalated"] += alarm.escalation_level > 0
        row["was_missed"] += was_missed(alarm, missed_ids)
    return {
        "counts": {
            "open": sections["open"],
            "missed": sections["missed"],
            "acknowledged_unresolved": sections["acknowledged"],
            "resolved": sections["resolved"],
            "escalated": sum(a.escalation_level > 0 for a in alarms),
            "ever_missed": sum(was_missed(a, missed_ids) for a in alarms),
        },
        "per_robot": [
            {
                "robot_id": robot_id,
                "alarms": row["alarms"],
                "open": row["open"],
                "missed": row["missed"],
                "acknowledged_unresolved": row["acknowledged"],
                "resolved": row["resolved"],
                "escalated": row["escalated"],
                "ever_missed": row["was_missed"],
            }
            for robot_id, row in sorted(per_robot.items(), key=_robot_order)
        ],
        "fatigue": fatigue_figures(in_shift, missed_ids, until),
        "alarms": [
            {"section": section_of(a), "was_missed": was_missed(a, missed_ids), "alarm": a}
            for a in alarms
        ],
    }


CSV_COLUMNS = (
    "section",
    "alarm_id",
    "kind",
    "state",
    "robot_id",
    "ward",
    "patient",
    "location",
    "transport_id",
    "raised_at",
    "transport_ended_at",
    "acknowledged_at",
    "acknowledged_by",
    "resolved_at",
    "resolved_by",
    "verdict",
    "reason",
    "escalation_level",
    "was_missed",
    "model_version",
)


def _cell(value) -> str:
    if value is None:
        return ""
    if isinstance(value, datetime):
        return value.isoformat()
    text = str(value)
    # A cell a spreadsheet would run as a formula is quoted as text (CSV injection).
    return "'" + text if text[:1] in ("=", "+", "-", "@", "\t", "\r") else text


def to_csv(report: dict, since: datetime, until: datetime, ward: str | None) -> str:
    out = io.StringIO()
    writer = csv.writer(out, lineterminator="\n")
    writer.writerow(
        [
            "# Vigil shift handover",
            f"ward {ward or 'all wards'}",
            f"from {since.isoformat()}",
            f"to {until.isoformat()}",
        ]
    )
    figures = (f"{k}={'' if v is None else v}" for k, v in report["fatigue"].items())
    writer.writerow(["# fatigue (alarms raised in the shift)", *figures])
    writer.writerow(CSV_COLUMNS)
    for row in report["alarms"]:
        a = row["alarm"]
        writer.writerow(
            [
                _cell(v)
                for v in (
                    row["section"],
                    a.id,
                    a.kind,
                    a.state,
                    a.robot_id,
                    a.ward,
                    a.patient,
                    a.location,
                    a.transport_id,
                    a.raised_at,
                    a.transport_ended_at,
                    a.acknowledged_at,
                    a.acknowledged_by,
                    a.resolved_at,
                    a.resolved_by,
                    a.verdict,
                    a.reason,
                    a.escalation_level,
                    "yes" if row["was_missed"] else "no",
                    a.model_version,
                )
            ]
        )
    return out.getvalue()

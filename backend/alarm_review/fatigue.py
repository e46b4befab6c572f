"""Alarm-fatigue statistics: load per shift and ward, false-alarm share, time to acknowledge.

Every figure comes with its sample size. Time to acknowledge counts the alarms nobody
acknowledged too, at the time they went without (until resolved, or until the end of the
period): leaving them out would make the slowest responses look fast."""

from __future__ import annotations

from collections import defaultdict
from collections.abc import Collection, Iterable
from dataclasses import dataclass
from datetime import datetime, timedelta
from statistics import median
from typing import Literal, Protocol

from backend.models.alarms import TECHNICAL_KINDS, AlarmKind, AlarmState, Verdict

ShiftName = Literal["early", "late", "night"]

#: Shift start hours (UTC): early 06-14, late 14-22, night 22-06 (the night belongs to its start).
SHIFT_STARTS: tuple[tuple[int, ShiftName], ...] = ((6, "early"), (14, "late"), (22, "night"))


class AlarmFacts(Protocol):
    kind: str
    ward: str
    raised_at: datetime
    acknowledged_at: datetime | None
    resolved_at: datetime | None
    verdict: str | None
    model_version: str | None


def shift_of(moment: datetime) -> tuple[datetime, ShiftName]:
    """The shift a moment falls in: (shift start, shift name)."""
    day = moment.replace(hour=0, minute=0, second=0, microsecond=0)
    if moment.hour < SHIFT_STARTS[0][0]:
        return day - timedelta(days=1) + timedelta(hours=SHIFT_STARTS[-1][0]), SHIFT_STARTS[-1][1]
    start_hour, name = max((s for s in SHIFT_STARTS if s[0] <= moment.hour), key=lambda s: s[0])
    return day + timedelta(hours=start_hour), name


def ack_wait_s(alarm: AlarmFacts, until: datetime) -> float:
    """How long an alarm waited for an acknowledgement; one nobody acknowledged counts until it
    was resolved, or until `until`."""
    if alarm.acknowledged_at is not None:
        waited_until = alarm.acknowledged_at
    else:
        waited_until = min(alarm.resolved_at or until, until)
    return max((waited_until - alarm.raised_at).total_seconds(), 0.0)


def was_missed(alarm: AlarmFacts, missed: Collection[int]) -> bool:
    """Missed now, or at some point (`missed`: ids of alarms that were)."""
    return (
        getattr(alarm, "state", None) == AlarmState.MISSED or getattr(alarm, "id", None) in missed
    )


@dataclass
class _Tally:
    alarms: int = 0
    emergencies: int = 0
    missed: int = 0
    resolved: int = 0
    false_alarms: int = 0
    acknowledged: int = 0
    unacknowledged: int = 0
    ack_seconds: list[float] | None = None

    def add(self, alarm: AlarmFacts, until: datetime, missed: Collection[int] = ()) -> None:
        self.alarms += 1
        self.emergencies += alarm.kind == AlarmKind.EMERGENCY
        self.missed += was_missed(alarm, missed)
        if alarm.verdict is not None:
            self.resolved += 1
            self.false_alarms += alarm.verdict == Verdict.FALSE_ALARM
        self.acknowledged += alarm.acknowledged_at is not None
        self.unacknowledged += alarm.acknowledged_at is None
        self.ack_seconds = self.ack_seconds or []
        self.ack_seconds.append(ack_wait_s(alarm, until))

    @property
    def median_ack_s(self) -> float | None:
        return round(median(self.ack_seconds), 3) if self.ack_seconds else None

    @property
    def false_share(self) -> float | None:
        return round(self.false_alarms / self.resolved, 4) if self.resolved else None


def fatigue_stats(
    alarms: Iterable[AlarmFacts], until: datetime, missed: Collection[int] = ()
) -> dict:
    """Per (shift, ward) and per model version; technical alarms count for load only by shift.
    `until` is the end of the period: an alarm still unacknowledged then counts as waiting
    until it. `missed`: ids of alarms that were "missed: needs review" at some point (those
    missed now count whatever it holds)."""
    by_shift: dict[tuple[datetime, ShiftName, str], _Tally] = defaultdict(_Tally)
    by_model: dict[str | None, _Tally] = defaultdict(_Tally)
    for alarm in alarms:
        start, name = shift_of(alarm.raised_at)
        by_shift[(start, name, alarm.ward)].add(alarm, until, missed)
        if alarm.kind not in TECHNICAL_KINDS:
            by_model[alarm.model_version].add(alarm, until, missed)
    shifts = [
        {
            "shift_start": start,
            "shift": name,
            "ward": ward,
            "alarms": t.alarms,
            "emergencies": t.emergencies,
            "missed": t.missed,
            "resolved": t.resolved,
            "false_alarms": t.false_alarms,
            "acknowledged": t.acknowledged,
            "unacknowledged": t.unacknowledged,
            "median_ack_s": t.median_ack_s,
        }
        for (start, name, ward), t in sorted(by_shift.items(), key=lambda kv: (kv[0][0], kv[0][2]))
    ]
    models = [
        {
            "model_version": version,
            "alarms": t.alarms,
            "missed": t.missed,
            "resolved": t.resolved,
            "false_alarms": t.false_alarms,
            "false_share": t.false_share,
            "acknowledged": t.acknowledged,
            "unacknowledged": t.unacknowledged,
            "median_ack_s": t.median_ack_s,
        }
        for version, t in sorted(by_model.items(), key=lambda kv: (kv[0] is None, kv[0] or ""))
    ]
    return {"shifts": shifts, "by_model": models}

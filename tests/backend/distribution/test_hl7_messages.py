"""The ORU^R40 is composed with python-hl7 and validated strictly by hl7apy (HL7 v2.6) per
message shape: every shape, at its longest values, validates; what an Alert Manager reads back
is what Vigil reported; a shape hl7apy refuses is never sent."""

from __future__ import annotations

import itertools
from dataclasses import replace
from datetime import UTC, datetime

import pytest

from backend.distribution import hl7_messages
from backend.distribution.hl7_messages import (
    AlertReport,
    Change,
    MessageError,
    build_alert_report,
    parse_alert_report,
    validate_strictly,
)

LONG = "x|^~\\&\r\n" * 60  # delimiters and line breaks, far past every clip


def _report(**fields) -> AlertReport:
    base = dict(
        control_id="C0FFEE",
        alarm_id=42,
        change=Change.RAISED,
        kind="emergency",
        kind_text="Patient emergency (fall suspected)",
        priority="high",
        technical=False,
        ward="ward-3a",
        robot_id="robot-7",
        patient="P-17",
        location="corridor B",
        raised_at=datetime(2026, 12, 7, 12, 3, 5, tzinfo=UTC),
        at=datetime(2026, 12, 7, 12, 3, 9, tzinfo=UTC),
        text="Fall suspected, robot-7, corridor B",
        escalation_level=0,
    )
    return AlertReport(**{**base, **fields})


OPTIONAL = ["robot_id", "patient", "location", "escalated_to", "by"]


def _longest(change: Change, technical: bool, present: tuple[bool, ...]) -> AlertReport:
    optional = {name: (LONG if on else None) for name, on in zip(OPTIONAL, present, strict=True)}
    longest = dict(text=LONG, ward=LONG, kind_text=LONG, escalation_level=99)
    return _report(change=change, technical=technical, **longest, **optional)


def test_every_shape_validates_strictly_at_its_longest_values():
    """A shape is which optional values are there (the change and the kind only change
    values): each, and each change, validated here whatever the process has seen before."""
    reports = [
        _longest(Change.RAISED, False, present)
        for present in itertools.product([False, True], repeat=len(OPTIONAL))
    ]
    reports += [_longest(change, True, (True,) * len(OPTIONAL)) for change in Change]
    for report in reports:
        validate_strictly(build_alert_report(report, facility=LONG), "ORU^R40")


def test_what_the_alert_manager_reads_is_what_vigil_reported():
    report = _report(change=Change.ACKNOWLEDGED, by="alice", text="acknowledged | by alice")
    received = parse_alert_report(build_alert_report(report))
    expected = ("C0FFEE", 42, Change.ACKNOWLEDGED)
    assert (received.control_id, received.alarm_id, received.change) == expected
    assert (received.kind, received.priority, received.ward) == ("emergency", "PH", "ward-3a")
    assert received.text == "acknowledged   by alice"  # a delimiter never reaches the wire


def test_a_shape_hl7apy_refuses_is_never_returned(monkeypatch):
    composed = hl7_messages.alert_report_segments

    def with_an_overlong_point_of_care(report, facility):
        # a shape of its own (PV1-2 left empty), with a value past PV1-3's 20 characters
        return [
            (name, {3: ("w" * 25, "room")} if name == "PV1" else fields)
            for name, fields in composed(report, facility)
        ]

    monkeypatch.setattr(hl7_messages, "alert_report_segments", with_an_overlong_point_of_care)
    with pytest.raises(MessageError, match="does not validate against HL7 v2.6.*max length"):
        build_alert_report(_report())


def test_the_outbox_keeps_the_report_as_json_and_builds_the_same_message():
    report = _report(escalated_to="charge nurse", escalation_level=1, change=Change.ESCALATED)
    again = AlertReport.from_json(report.to_json())
    assert again == report
    assert build_alert_report(again).split("\r")[1:] == build_alert_report(report).split("\r")[1:]
    assert replace(again, control_id="OTHER") != report

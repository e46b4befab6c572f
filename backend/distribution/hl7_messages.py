"""The HL7 v2.6 messages of IHE PCD Alert Communication Management, built and checked with
maintained libraries (never by splicing strings):

- `ORU^R40` (Report Alert, PCD-04), Vigil → Alert Manager: composed with python-hl7's
  containers (under a millisecond) and validated strictly by hl7apy against the v2.6 ORU_R01
  structure (the structure IHE PCD names for R40) the first time each shape of message occurs
  in the process; values are cleaned of delimiters and clipped to their v2.6 maximum lengths,
  so a message of a validated shape is valid (a test validates every shape at its longest
  values). Building every message with hl7apy took ~25 ms each: at 100 robots the sender's
  queue, not the network, set the latency. One OBR per alert; the OBX rows carry the IHE PCD
  ACM alert attributes (event phase, alarm state, inactivation state, priority, alert type)
  and what a phone shows.
- `ACK` (the Alert Manager's accept acknowledgement): read with python-hl7.
- `ORA^R41` (Report Alert Status, PCD-05), Alert Manager → Vigil: what happened to the alert on
  the clinician's device. v2.6 has no PRT segment, so the disposition rides in one OBX: OBX-5
  the status (delivered, read, accepted, rejected), OBX-14 when, OBX-16 the clinician (XCN),
  OBX-18 the device (EI); MSA-2 names the ORU^R40 it answers and OBR-2 the alert.
  `build_alert_status` (the simulator's and the tests' Alert Manager) builds it with hl7apy.
"""

from __future__ import annotations

import json
import secrets
from dataclasses import asdict, dataclass
from datetime import UTC, datetime
from enum import StrEnum

import hl7
from hl7apy.consts import VALIDATION_LEVEL
from hl7apy.core import Message, Segment
from hl7apy.exceptions import HL7apyException
from hl7apy.parser import parse_message

VERSION = "2.6"
SENDING_APPLICATION = "VIGIL"
ALERT_IDENTIFIER_NAMESPACE = "VIGIL"
#: IHE PCD ACM message profile (MSH-21)
ACM_PROFILE = "IHE_PCD_ACM_001^IHE PCD^1.3.6.1.4.1.19376.1.6.4.4.4^ISO"
MDC_EVT_ALARM = "196616^MDC_EVT_ALARM^MDC"
DISPOSITION_CODE = "VIGIL_DISPOSITION^Alert dissemination status^99VIGIL"
#: v2.6 maximum lengths of the IS components Vigil fills: PV1-3 point of care and room, MSH-4
#: namespace id (the phone text in OBX-5 carries the full ward and location)
PL_MAX = HD_MAX = 20


class Change(StrEnum):
    """A change of an alarm that goes to the Alert Manager."""

    RAISED = "raised"
    ESCALATED = "escalated"
    MISSED = "missed"
    REALARMED = "realarmed"
    ACKNOWLEDGED = "acknowledged"
    RESOLVED = "resolved"
    CLEARED = "cleared"


class Disposition(StrEnum):
    """What the Alert Manager reports of an alert on a clinician's device (ORA^R41)."""

    DELIVERED = "delivered"
    READ = "read"
    ACCEPTED = "accepted"
    REJECTED = "rejected"


# IHE PCD ACM attributes per change: (event phase, alarm state, inactivation state)
_PHASE = {
    Change.RAISED: ("start", "active", "enabled"),
    Change.ESCALATED: ("escalate", "active", "enabled"),
    Change.REALARMED: ("escalate", "active", "enabled"),
    Change.MISSED: ("escalate", "latched", "enabled"),
    Change.ACKNOWLEDGED: ("update", "active", "alert-acknowledged"),
    Change.RESOLVED: ("end", "inactive", "alert-acknowledged"),
    Change.CLEARED: ("end", "inactive", "enabled"),
}
_PRIORITY = {"high": "PH", "medium": "PM", "technical": "PL"}


@dataclass(frozen=True, slots=True)
class AlertReport:
    """One alarm change as the Alert Manager gets it."""

    control_id: str
    alarm_id: int
    change: Change
    kind: str
    kind_text: str
    priority: str
    technical: bool
    ward: str
    robot_id: str | None
    patient: str | None
    location: str | None
    raised_at: datetime
    at: datetime
    text: str
    escalation_level: int = 0
    escalated_to: str | None = None
    by: str | None = None

    def to_json(self) -> str:
        """What the outbox keeps until the sender builds the message (outside the change's
        transaction: building and validating takes tens of milliseconds)."""
        fields = asdict(self)
        fields["change"] = self.change.value
        fields["raised_at"] = self.raised_at.isoformat()
        fields["at"] = self.at.isoformat()
        return json.dumps(fields, separators=(",", ":"))

    @classmethod
    def from_json(cls, text: str) -> AlertReport:
        fields = json.loads(text)
        fields["change"] = Change(fields["change"])
        fields["raised_at"] = datetime.fromisoformat(fields["raised_at"])
        fields["at"] = datetime.fromisoformat(fields["at"])
        return cls(**fields)


@dataclass(frozen=True, slots=True)
class Ack:
    code: str  # AA / CA accepted, AE / CE error, AR / CR rejected
    control_id: str  # MSA-2: the message it acknowledges
    text: str

    @property
    def accepted(self) -> bool:
        return self.code in ("AA", "CA")

    @property
    def rejected(self) -> bool:
        """AR: the receiver could not take it now; sending it again may succeed."""
        return self.code in ("AR", "CR")


@dataclass(frozen=True, slots=True)
class AlertStatus:
    """One ORA^R41: a disposition of an alert on a clinician's device."""

    control_id: str  # MSH-10 of the ORA^R41 itself
    answers: str  # MSA-2: the ORU^R40 it reports on
    alert: str  # OBR-2 entity identifier
    disposition: Disposition
    clinician_id: str
    clinician: str  # "Anna Berg"
    device: str  # "Anna's phone"
    at: datetime


class MessageError(ValueError):
    """A message that is not what IHE PCD ACM (as Vigil speaks it) says, naming the field."""


def hl7_time(moment: datetime) -> str:
    return moment.astimezone(UTC).strftime("%Y%m%d%H%M%S") + "+0000"


def parse_hl7_time(text: str) -> datetime:
    digits = text.split("+")[0].split("-")[0].split(".")[0]
    try:
        return datetime.strptime(digits.ljust(14, "0")[:14], "%Y%m%d%H%M%S").replace(tzinfo=UTC)
    except ValueError:
        raise MessageError(f"not an HL7 date/time: {text!r}") from None


def alert_identifier(alarm_id: int) -> str:
    return f"VIGIL-ALARM-{alarm_id}"


def alarm_of_identifier(identifier: str) -> int | None:
    prefix = "VIGIL-ALARM-"
    if identifier.startswith(prefix) and identifier[len(prefix) :].isdigit():
        return int(identifier[len(prefix) :])
    return None


def new_control_id() -> str:
    return secrets.token_hex(10).upper()


def _clean(text: str | None, limit: int = 199) -> str:
    """A value for one HL7 component: no delimiters, no line breaks."""
    if not text:
        return ""
    for delimiter in "|^~\\&\r\n":
        text = text.replace(delimiter, " ")
    return text.strip()[:limit]


def _header_fields(message_type: str, control_id: str, facility: str) -> dict[int, str | tuple]:
    return {
        3: SENDING_APPLICATION,
        4: _clean(facility, HD_MAX) or "HOSPITAL",
        5: "ACM",
        7: hl7_time(datetime.now(UTC)),
        9: tuple(message_type.split("^")),
        10: control_id,
        11: "P",
        12: VERSION,
        15: "AL",
        16: "NE",
        18: "UNICODE UTF-8",
        21: tuple(ACM_PROFILE.split("^")),
    }


def _header(message: Message | Segment, message_type: str, control_id: str, facility: str):
    msh = message.msh if isinstance(message, Message) else message
    msh.msh_3 = SENDING_APPLICATION
    msh.msh_4 = _clean(facility, HD_MAX) or "HOSPITAL"
    msh.msh_5 = "ACM"
    msh.msh_7 = hl7_time(datetime.now(UTC))
    msh.msh_9 = message_type
    msh.msh_10 = control_id
    msh.msh_11 = "P"
    msh.msh_12 = VERSION
    msh.msh_15 = "AL"
    msh.msh_16 = "NE"
    msh.msh_18 = "UNICODE UTF-8"
    msh.msh_21 = ACM_PROFILE


Components = tuple[str, ...]


def _er7(segments: list[tuple[str, dict[int, str | Components]]]) -> str:
    """ER7 text from segments given as {field number: value or components}, composed with
    python-hl7's containers (values are `_clean`ed: they hold no delimiter to escape)."""

    def field(value: str | Components) -> hl7.Field:
        components = list(value) if isinstance(value, tuple) else [value]
        while len(components) > 1 and not components[-1]:
            components.pop()  # trailing empty components are left out, as ER7 writes them
        return hl7.Field("~", [hl7.Repetition("^", components)])

    rendered = []
    for name, fields in segments:
        size = max(fields)
        if name == "MSH":  # MSH-1 is the field separator itself, MSH-2 the encoding characters
            values = [name, "|", "^~\\&", *(field(fields.get(n, "")) for n in range(3, size + 1))]
        else:
            values = [name, *(field(fields.get(n, "")) for n in range(1, size + 1))]
        rendered.append(hl7.Segment("|", values))
    return str(hl7.Message("\r", rendered)).rstrip("\r")


#: Message shapes (segments, which fields and components are filled) hl7apy has validated
#: strictly against HL7 v2.6 in this process. Values are cleaned and clipped, so a message of
#: a validated shape is valid too (tests validate every shape at its longest values).
_VALIDATED_SHAPES: set[tuple] = set()


def _shape(segments: list[tuple[str, dict[int, str | Components]]]) -> tuple:
    def filled(value: str | Components) -> tuple[bool, ...]:
        return tuple(bool(c) for c in (value if isinstance(value, tuple) else (value,)))

    return tuple(
        (name, tuple((n, filled(v)) for n, v in sorted(fields.items())))
        + ((fields[2],) if name == "OBX" else ())  # the value type
        for name, fields in segments
    )


def validate_strictly(text: str, what: str) -> None:
    """hl7apy's strict HL7 v2.6 validation of one message (parse, then validate)."""
    try:
        message = parse_message(text, validation_level=VALIDATION_LEVEL.STRICT)
        valid = message.validate()
    except HL7apyException as error:
        raise MessageError(f"{what} does not validate against HL7 v2.6: {error}") from None
    if not valid:
        raise MessageError(f"{what} does not validate against HL7 v2.6")


def alert_report_segments(report: AlertReport, facility: str) -> list[tuple[str, dict]]:
    phase, state, inactivation = _PHASE[report.change]
    rows: list[tuple[str, Components, str]] = [
        (
            "ST",
            (f"VIGIL_{report.kind.upper()}", _clean(report.kind_text, 80), "99VIGIL"),
            _clean(report.text),
        ),
        ("ST", ("68481", "MDC_ATTR_EVENT_PHASE", "MDC"), phase),
        ("ST", ("68482", "MDC_ATTR_ALARM_STATE", "MDC"), state),
        ("ST", ("68483", "MDC_ATTR_ALARM_INACTIVATION_STATE", "MDC"), inactivation),
        ("ST", ("68484", "MDC_ATTR_ALARM_PRIORITY", "MDC"), _PRIORITY.get(report.priority, "PL")),
        ("ST", ("68485", "MDC_ATTR_ALERT_TYPE", "MDC"), "ST" if report.technical else "SP"),
        ("ST", ("VIGIL_CHANGE", "Alarm change", "99VIGIL"), report.change.value),
        ("NM", ("VIGIL_ESCALATION", "Escalation level", "99VIGIL"), str(report.escalation_level)),
    ]
    if report.robot_id:
        rows.append(("ST", ("VIGIL_SOURCE", "Robot", "99VIGIL"), _clean(report.robot_id, 64)))
    if report.escalated_to:
        escalated_to = _clean(report.escalated_to)
        rows.append(("ST", ("VIGIL_ESCALATED_TO", "Escalated to", "99VIGIL"), escalated_to))
    if report.by:
        rows.append(("ST", ("VIGIL_BY", "By", "99VIGIL"), _clean(report.by)))
    identifier = (alert_identifier(report.alarm_id), ALERT_IDENTIFIER_NAMESPACE)
    segments: list[tuple[str, dict]] = [
        ("MSH", _header_fields("ORU^R40^ORU_R01", report.control_id, facility)),
        (
            "PID",
            {
                3: (_clean(report.patient, 60) or "unknown", "", "", "VIGIL"),
                5: ("", "", "", "", "", "", "U"),
            },
        ),
        ("PV1", {2: "I", 3: (_clean(report.ward, PL_MAX), _clean(report.location, PL_MAX))}),
        (
            "OBR",
            {
                1: "1",
                2: identifier,
                3: identifier,
                4: tuple(MDC_EVT_ALARM.split("^")),
                7: hl7_time(report.raised_at),
            },
        ),
    ]
    for number, (value_type, code, value) in enumerate(rows, start=1):
        segments.append(
            (
                "OBX",
                {
                    1: str(number),
                    2: value_type,
                    3: code,
                    4: f"1.0.0.{number}",
                    5: value,
                    11: "F",
                    14: hl7_time(report.at),
                },
            )
        )
    return segments


def build_alert_report(report: AlertReport, facility: str = "HOSPITAL") -> str:
    """The ORU^R40 of one alarm change (ER7, segments joined by carriage returns), composed
    with python-hl7 (well under a millisecond) and validated strictly by hl7apy against the
    v2.6 ORU_R01 structure the first time its shape occurs (tens of milliseconds)."""
    segments = alert_report_segments(report, facility)
    text = _er7(segments)
    shape = _shape(segments)
    if shape not in _VALIDATED_SHAPES:
        validate_strictly(text, "ORU^R40")
        _VALIDATED_SHAPES.add(shape)
    return text


def _parse(text: str) -> hl7.Message:
    try:
        return hl7.parse(text)
    except Exception as error:  # python-hl7 raises several kinds for a malformed message
        raise MessageError(f"not an HL7 v2 message: {error}") from None


def _field(message: hl7.Message, segment: str, index: int) -> str:
    try:
        return str(message.segment(segment)[index]) if len(message.segment(segment)) > index else ""
    except KeyError:
        raise MessageError(f"no {segment} segment") from None


def message_type(text: str) -> str:
    """MSH-9 as "ORU^R40" (code^trigger)."""
    parsed = _parse(text)
    kind = parsed.segment("MSH")[9]
    return "^".join(str(part) for part in list(kind[0])[:2]) if kind else ""


def control_id_of(text: str) -> str:
    return _field(_parse(text), "MSH", 10)


def parse_ack(text: str) -> Ack:
    parsed = _parse(text)
    code = _field(parsed, "MSA", 1)
    if code not in ("AA", "AE", "AR", "CA", "CE", "CR"):
        raise MessageError(f"MSA-1: not an acknowledgement code: {code!r}")
    return Ack(code=code, control_id=_field(parsed, "MSA", 2), text=_field(parsed, "MSA", 3))


def ack_for(
    text: str, code: str = "AA", error: str | None = None, application: str = SENDING_APPLICATION
) -> str:
    """The accept acknowledgement of a received message (python-hl7 builds it); `error` goes
    into MSA-3."""
    ack = _parse(text).create_ack(
        ack_code=code, message_id=new_control_id(), application=application
    )
    if error:
        ack.assign_field(_clean(error), "MSA", 1, 3)
    return str(ack)


def parse_alert_status(text: str) -> AlertStatus:
    """An ORA^R41 as Vigil reads it; MessageError names what is missing or wrong."""
    parsed = _parse(text)
    if message_type(text) != "ORA^R41":
        raise MessageError(f"MSH-9: expected ORA^R41, got {message_type(text)!r}")
    try:
        obx = parsed.segment("OBX")
    except KeyError:
        raise MessageError("no OBX segment (the disposition)") from None
    status = str(obx[5]) if len(obx) > 5 else ""
    try:
        disposition = Disposition(status.lower())
    except ValueError:
        raise MessageError(
            f"OBX-5: unknown disposition {status!r} (delivered, read, accepted, rejected)"
        ) from None
    clinician = obx[16] if len(obx) > 16 else None
    parts = [str(p) for p in list(clinician[0])] if clinician else []
    clinician_id = parts[0] if parts else ""
    family, given = (parts + ["", "", ""])[1:3]
    name = " ".join(p for p in (given, family) if p) or clinician_id
    if not name:
        raise MessageError("OBX-16: no clinician named")
    device = obx[18] if len(obx) > 18 else None
    device_parts = [str(p) for p in list(device[0])] if device else []
    device_name = (device_parts[1] if len(device_parts) > 1 else "") or (
        device_parts[0] if device_parts else ""
    )
    at = str(obx[14]) if len(obx) > 14 else ""
    answers = _field(parsed, "MSA", 2)
    if not answers:
        raise MessageError("MSA-2: which ORU^R40 this status answers is missing")
    alert = _field(parsed, "OBR", 2).split("^")[0]
    return AlertStatus(
        control_id=_field(parsed, "MSH", 10),
        answers=answers,
        alert=alert,
        disposition=disposition,
        clinician_id=clinician_id,
        clinician=name,
        device=device_name or "device",
        at=parse_hl7_time(at) if at else datetime.now(UTC),
    )


@dataclass(frozen=True, slots=True)
class ReceivedReport:
    """An ORU^R40 as an Alert Manager reads it (the simulator's and the tests')."""

    control_id: str
    alarm_id: int
    change: Change
    kind: str
    priority: str
    ward: str
    text: str  # what the phone shows


def parse_alert_report(text: str) -> ReceivedReport:
    parsed = _parse(text)
    if message_type(text) != "ORU^R40":
        raise MessageError(f"MSH-9: expected ORU^R40, got {message_type(text)!r}")
    alarm_id = alarm_of_identifier(_field(parsed, "OBR", 2).split("^")[0])
    if alarm_id is None:
        raise MessageError(f"OBR-2: not a Vigil alert identifier: {_field(parsed, 'OBR', 2)!r}")
    values: dict[str, str] = {}
    kind = ""
    for segment in parsed.segments("OBX"):
        code = str(segment[3][0][0]) if len(segment) > 3 and segment[3] else ""
        value = str(segment[5]) if len(segment) > 5 else ""
        if code.startswith("VIGIL_") and not kind and code not in _OWN_CODES:
            kind, values["text"] = code.removeprefix("VIGIL_").lower(), value
        values[code] = value
    try:
        change = Change(values.get("VIGIL_CHANGE", ""))
    except ValueError:
        raise MessageError(f"OBX VIGIL_CHANGE: {values.get('VIGIL_CHANGE')!r}") from None
    return ReceivedReport(
        control_id=_field(parsed, "MSH", 10),
        alarm_id=alarm_id,
        change=change,
        kind=kind,
        priority=values.get("68484", ""),
        ward=_field(parsed, "PV1", 3).split("^")[0],
        text=values.get("text", ""),
    )


_OWN_CODES = {"VIGIL_CHANGE", "VIGIL_ESCALATION", "VIGIL_SOURCE", "VIGIL_ESCALATED_TO", "VIGIL_BY"}


def build_alert_status(
    answers: str,
    alarm_id: int,
    disposition: Disposition,
    clinician_id: str,
    clinician_family: str,
    clinician_given: str,
    device_id: str,
    device: str,
    at: datetime,
    facility: str = "ACM",
) -> str:
    """An Alert Manager's ORA^R41 (the simulator's and the tests'), segment by segment with
    hl7apy: v2.6 knows no ORA_R41 structure, each segment is validated on its own."""
    msh = Segment("MSH", version=VERSION, validation_level=VALIDATION_LEVEL.STRICT)
    msh.msh_1 = "|"
    msh.msh_2 = "^~\\&"
    _header(msh, "ORA^R41^ORA_R41", new_control_id(), facility)
    msh.msh_3, msh.msh_5 = "ACM", SENDING_APPLICATION
    msa = Segment("MSA", version=VERSION, validation_level=VALIDATION_LEVEL.STRICT)
    msa.msa_1 = "AA"
    msa.msa_2 = answers
    obr = Segment("OBR", version=VERSION, validation_level=VALIDATION_LEVEL.STRICT)
    obr.obr_1 = "1"
    obr.obr_2 = f"{alert_identifier(alarm_id)}^{ALERT_IDENTIFIER_NAMESPACE}"
    obr.obr_4 = MDC_EVT_ALARM
    obx = Segment("OBX", version=VERSION, validation_level=VALIDATION_LEVEL.STRICT)
    obx.obx_1 = "1"
    obx.obx_2 = "ST"
    obx.obx_3 = DISPOSITION_CODE
    obx.obx_4 = "1"
    obx.obx_5 = disposition.value
    obx.obx_11 = "F"
    obx.obx_14 = hl7_time(at)
    obx.obx_16 = f"{_clean(clinician_id)}^{_clean(clinician_family)}^{_clean(clinician_given)}"
    obx.obx_18 = f"{_clean(device_id)}^{_clean(device)}"
    for segment in (msh, msa, obr, obx):
        if not segment.validate():
            raise MessageError(f"{segment.name} does not validate against HL7 v2.6")
    return "\r".join(segment.to_er7() for segment in (msh, msa, obr, obx))

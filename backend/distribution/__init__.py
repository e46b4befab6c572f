"""Alarm distribution (IHE PCD Alert Communication Management): Vigil as Alert Reporter.

Each alarm change is queued in the same transaction as the change (`alarm_messages`, the
outbox), sent as an HL7 v2.6 ORU^R40 over MLLP to the ward's Alert Manager and kept until its
ACK arrives; the Alert Manager's ORA^R41 dispositions (delivered, read, accepted, rejected by a
named clinician) come back through a small MLLP listener. This package knows HL7, MLLP and the
outbox; what a disposition does to an alarm is the alarm domain's (`backend.alarms.distribution`).
"""

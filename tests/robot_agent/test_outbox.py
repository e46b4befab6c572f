"""The outbox: sequence numbers, acknowledgement trimming, the disk budget policy, restarts."""

from __future__ import annotations

import json
import time

import pytest

from robot_agent.outbox import Outbox, Priority


def body(i: int, decision: str = "normal", size: int = 0) -> str:
    text = json.dumps({"ts": float(i), "decision": decision, "pad": ""})
    return text[:-2] + "x" * max(0, size - len(text)) + '"}'  # exactly `size` bytes


def seqs(outbox: Outbox) -> list[int | None]:
    return [m.seq for m in outbox.pending()]


def test_frames_get_consecutive_sequence_numbers_that_survive_a_restart(tmp_path):
    outbox = Outbox(tmp_path / "o.sqlite")
    assert [outbox.add_frame(body(i), Priority.NORMAL) for i in range(3)] == [0, 1, 2]
    outbox.acknowledge(2)
    outbox.close()
    reopened = Outbox(tmp_path / "o.sqlite")
    assert reopened.add_frame(body(3), Priority.NORMAL) == 3  # never reused after trimming
    frame = json.loads(reopened.pending()[0].text)
    assert frame["seq"] == 3 and frame["ts"] == 3.0


def test_acknowledgement_trims_frames_and_the_transport_messages_before_them(tmp_path):
    outbox = Outbox(tmp_path / "o.sqlite")
    outbox.add_message('{"type":"transport_start"}')
    for i in range(4):
        outbox.add_frame(body(i), Priority.NORMAL)
    outbox.add_message('{"type":"transport_end"}')
    assert seqs(outbox) == [None, 0, 1, 2, 3, None]
    assert outbox.acknowledge(1) == 3  # the start and frames 0, 1
    assert seqs(outbox) == [2, 3, None]
    assert outbox.acknowledge(1) == 0  # an old ack changes nothing
    outbox.acknowledge(3)
    assert seqs(outbox) == [None]  # the end is confirmed only by a later frame's ack
    outbox.add_frame(body(4), Priority.NORMAL)
    outbox.acknowledge(4)
    assert outbox.pending() == [] and outbox.status().pending_bytes == 0


def test_pending_reads_in_queue_order_after_a_cursor(tmp_path):
    outbox = Outbox(tmp_path / "o.sqlite")
    for i in range(5):
        outbox.add_frame(body(i), Priority.NORMAL)
    first = outbox.pending(limit=2)
    assert [m.seq for m in first] == [0, 1]
    assert [m.seq for m in outbox.pending(after_row=first[-1].row_id)] == [2, 3, 4]


def test_over_budget_oldest_normal_frames_go_first_then_pause_never_emergency(tmp_path, caplog):
    size = 200
    outbox = Outbox(tmp_path / "o.sqlite", budget_bytes=10 * size)
    kinds = ["emergency", "normal", "pause", "normal", "emergency"] * 2
    priority = {"normal": Priority.NORMAL, "pause": Priority.PAUSE, "emergency": Priority.KEPT}
    for i, kind in enumerate(kinds):
        outbox.add_frame(body(i, kind, size=size), priority[kind])
    assert outbox.dropped_total == 0 and seqs(outbox) == list(range(10))
    outbox.add_frame(body(10, "normal", size=size), Priority.NORMAL)  # 11 frames, room for 10
    assert seqs(outbox) == [0, 2, 3, 4, 5, 6, 7, 8, 9, 10]  # the oldest Normal (1) dropped
    for i in range(11, 14):
        outbox.add_frame(body(i, "emergency", size=size), Priority.KEPT)
    # Normal frames 3, 6, 8 go, oldest first.
    assert seqs(outbox) == [0, 2, 4, 5, 7, 9, 10, 11, 12, 13]
    for i in range(14, 20):
        outbox.add_frame(body(i, "emergency", size=size), Priority.KEPT)
    kept = [json.loads(m.text)["decision"] for m in outbox.pending()]
    assert kept.count("emergency") == 4 + 3 + 6  # every Emergency frame is still there
    assert "normal" not in kept and "pause" not in kept
    assert outbox.status().pending_bytes > outbox.budget_bytes  # grows: Emergency never dropped
    assert outbox.dropped_total == 20 - len(kept)
    assert "dropped the" in caplog.text and "never dropped" in caplog.text
    outbox.close()
    assert Outbox(tmp_path / "o.sqlite").dropped_total == 20 - len(kept)  # persistent count


def test_welcome_trims_what_the_backend_already_stored(tmp_path):
    outbox = Outbox(tmp_path / "o.sqlite")
    outbox.on_welcome(None)  # first connection: the backend had nothing of this robot
    for i in range(5):
        outbox.add_frame(body(i), Priority.NORMAL)
    outbox.on_welcome(2)
    assert seqs(outbox) == [3, 4]
    outbox.on_welcome(None)
    assert seqs(outbox) == [3, 4]


def test_fresh_outbox_continues_after_the_backends_last_sequence_number(tmp_path):
    """A robot with a new outbox file must not reuse numbers the backend has: it would take the
    new frames for duplicates and drop them."""
    outbox = Outbox(tmp_path / "o.sqlite")
    outbox.add_message('{"type":"transport_start"}')
    for i in range(3):
        outbox.add_frame(body(i), Priority.NORMAL)
    outbox.on_welcome(41)
    assert seqs(outbox) == [None, 42, 43, 44]
    assert [json.loads(m.text)["seq"] for m in outbox.pending()[1:]] == [42, 43, 44]
    assert outbox.add_frame(body(3), Priority.NORMAL) == 45
    outbox.acknowledge(42)
    assert seqs(outbox) == [43, 44, 45]


def test_budget_must_be_positive(tmp_path):
    with pytest.raises(ValueError, match="budget_bytes"):
        Outbox(tmp_path / "o.sqlite", budget_bytes=0)


def test_fresh_outbox_with_more_frames_than_the_backend_renumbers_them_all(tmp_path):
    """Offline since installation: 8 frames waiting, the backend has 0..4 from an old outbox.
    Trimming 0..4 as 'already stored' would lose five new frames."""
    outbox = Outbox(tmp_path / "o.sqlite")
    for i in range(8):
        outbox.add_frame(body(i), Priority.NORMAL)
    outbox.on_welcome(4)
    assert seqs(outbox) == list(range(5, 13))
    outbox.close()
    reopened = Outbox(tmp_path / "o.sqlite")
    reopened.on_welcome(6)  # later welcomes trim as usual
    assert seqs(reopened) == list(range(7, 13))


def test_emergency_frames_are_fsynced_in_the_background_normal_frames_are_not(tmp_path):
    outbox = Outbox(tmp_path / "o.sqlite")
    outbox.add_frame(body(0), Priority.NORMAL)
    time.sleep(0.2)
    assert outbox._syncer.synced == 0
    outbox.add_frame(body(1, "emergency"), Priority.KEPT)
    deadline = time.monotonic() + 5
    while outbox._syncer.synced == 0 and time.monotonic() < deadline:
        time.sleep(0.01)
    assert outbox._syncer.synced >= 1
    outbox.close()

"""Outbox semantics: sequence numbers, ack, resend after restart, bounded disk policy."""

from robot_agent.outbox import Outbox


def frame(i: int) -> dict:
    return {"ts": float(i), "keypoints": [[0.0, 0.0, 0.0]] * 25}


def test_every_frame_gets_the_next_seq_and_stays_until_acked(tmp_path):
    box = Outbox(tmp_path / "o.sqlite")
    box.put_control({"type": "transport_start", "transport_id": "t1", "mode": "walking", "ts": 0})
    seqs = [box.put_frame(frame(i), emergency=False) for i in range(5)]
    assert seqs == [0, 1, 2, 3, 4] and len(box) == 5
    items = box.pending()
    assert items[0].seq is None and items[0].body["type"] == "transport_start"
    assert [i.seq for i in items[1:]] == seqs and items[1].body["seq"] == 0
    assert box.ack(2) == 3
    assert [i.seq for i in box.pending()] == [3, 4]  # the control message went with seq 0
    assert box.ack(1) == 0  # an old ack changes nothing
    assert len(box) == 2


def test_unacked_frames_survive_a_restart_and_numbering_continues(tmp_path):
    box = Outbox(tmp_path / "o.sqlite")
    for i in range(3):
        box.put_frame(frame(i), emergency=i == 1)
    box.ack(0)
    box.close()
    again = Outbox(tmp_path / "o.sqlite")
    assert [i.seq for i in again.pending()] == [1, 2] and len(again) == 2
    assert again.put_frame(frame(9), emergency=False) == 3


def test_backend_ahead_of_a_new_outbox_never_gets_a_reused_seq(tmp_path):
    box = Outbox(tmp_path / "fresh.sqlite")
    box.ack(41)  # welcome said the backend holds frames up to 41
    assert box.put_frame(frame(0), emergency=False) == 42


def test_disk_bound_drops_oldest_normal_frames_never_emergency(tmp_path):
    box = Outbox(tmp_path / "o.sqlite", max_frames=4)
    kinds = [True, False, True, False, False, False, True, True, True]
    for i, emergency in enumerate(kinds):
        box.put_frame(frame(i), emergency=emergency)
    kept = {i.seq for i in box.pending()}
    emergencies = {i for i, e in enumerate(kinds) if e}
    assert emergencies <= kept  # every Emergency frame is kept, even past the bound
    assert kept == emergencies  # the normal ones were dropped, oldest first
    assert box.dropped == 4
    box.put_frame(frame(9), emergency=False)  # only emergencies left: the newest normal goes
    assert box.emergency_count() == 5


def test_fresh_outbox_renumbers_frames_after_what_the_backend_holds(tmp_path):
    box = Outbox(tmp_path / "new-disk.sqlite")
    box.put_frame(frame(0), emergency=False)
    box.put_frame(frame(1), emergency=True)
    box.welcome(41)  # the backend already holds 0..41 from this robot's previous disk
    assert [(i.seq, i.body["seq"]) for i in box.pending()] == [(42, 42), (43, 43)]
    assert box.put_frame(frame(2), emergency=False) == 44
    box.welcome(43)  # a later reconnect: a plain ack, no renumbering
    assert [i.seq for i in box.pending()] == [44]

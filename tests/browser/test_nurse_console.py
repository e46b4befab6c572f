"""The nurse console in Debian Chromium against the real backend and a simulated robot."""

from __future__ import annotations

import csv
import io
import re
import time
from datetime import timedelta
from pathlib import Path

import pytest
from playwright.sync_api import expect
from sqlalchemy import select

from backend.alarms import service
from backend.alarms.service import DecisionEvidence
from backend.db import transaction
from backend.models import (
    Alarm,
    AlarmEvent,
    AlarmKind,
    AnnotationSegment,
    Frame,
    Robot,
    Transport,
    User,
)
from backend.models._types import utcnow
from vigil.protocol import TransportEnd

from .live_server import ROBOT_TOKEN, SCREENSHOTS, LiveServer, list_alarm_ids, sign_in
from .simulated_robot import SimulatedRobot, fall_frames

pytestmark = pytest.mark.browser


def _card(page, alarm_id: int | None = None):
    selector = "article.alarm" + (f"[data-alarm-id='{alarm_id}']" if alarm_id else "")
    return page.locator(selector)


def test_foundation_slice_emergency_to_one_click_acknowledgement(live_server, page, db):
    sign_in(page, live_server.base_url)
    expect(page).to_have_url(f"{live_server.base_url}/nurse")
    expect(page.locator("main.board")).to_have_attribute("data-link", "live")

    with SimulatedRobot(live_server.robot_ws_url, "robot-a", ROBOT_TOKEN) as robot:
        robot.start_transport("t-1", patient="P-17", location="corridor B")
        robot.stream(fall_frames(0, time.time() - 5, "t-1"))

    card = _card(page)
    expect(card).to_have_count(1)
    expect(card).to_contain_text("Emergency")
    expect(card).to_contain_text("P-17")
    alarm_id = int(card.get_attribute("data-alarm-id"))

    card.get_by_role("button", name="Acknowledge").click()
    expect(card).to_have_attribute("data-state", "acknowledged")

    with db() as session:
        alarm = session.get(Alarm, alarm_id)
        nurse = session.scalars(select(User).where(User.username == "nina")).one()
        assert alarm.state == "acknowledged"
        assert alarm.acknowledged_by_id == nurse.id
        assert alarm.acknowledged_at is not None
        assert session.scalars(select(Frame)).first() is not None


def test_fall_alarm_sounds_is_acknowledged_resolved_and_becomes_a_label(live_server, page, db):
    SCREENSHOTS.mkdir(parents=True, exist_ok=True)
    sign_in(page, live_server.base_url)
    board = page.locator("main.board")
    expect(board).to_have_attribute("data-link", "live")
    expect(page.get_by_text("Sound is locked")).to_be_visible()
    expect(board).to_have_attribute("data-audio-state", "locked")
    page.get_by_role("button", name="Start shift").click()
    expect(board).to_have_attribute("data-audio-state", "ready")
    expect(page.get_by_text("Sound is locked")).to_have_count(0)

    frames = fall_frames(100, time.time() - 5, "t-2", model_version="mlp-7")
    first_emergency = next(i for i, f in enumerate(frames) if f.decision == "emergency")
    with SimulatedRobot(live_server.robot_ws_url, "robot-a", ROBOT_TOKEN) as robot:
        robot.start_transport("t-2", patient="P-42", location="ward A, corridor 3")
        robot.stream(frames[:first_emergency])
        robot.send_batch(frames[first_emergency : first_emergency + 1])
        sent = time.monotonic()
        card = _card(page)
        card.wait_for(state="visible", timeout=1000)
        shown_after = time.monotonic() - sent
        robot.wait_ack(frames[first_emergency].seq)
        robot.stream(frames[first_emergency + 1 :])
    assert shown_after < 1.0, f"alarm took {shown_after:.2f} s to show"

    expect(board).to_have_attribute("data-audio-state", "playing")
    expect(page).to_have_title("(1) Alarms · Vigil")
    expect(card).to_have_class(re.compile(r"alarm-emergency"))
    for text in ("robot-a", "P-42", "ward A, corridor 3", "t-2", "ago"):
        expect(card).to_contain_text(text)
    alarm_id = int(card.get_attribute("data-alarm-id"))
    page.screenshot(path=str(SCREENSHOTS / "nurse_board.png"), full_page=True)

    card.get_by_role("button", name="Acknowledge").click()
    expect(card).to_have_attribute("data-state", "acknowledged")
    expect(board).to_have_attribute("data-audio-state", "ready")
    with db() as session:
        assert session.get(Alarm, alarm_id).state == "acknowledged"
        events = session.scalars(
            select(AlarmEvent).where(AlarmEvent.alarm_id == alarm_id).order_by(AlarmEvent.id)
        ).all()
        assert [(e.action, e.to_state, e.actor) for e in events] == [
            ("raise", "open", "robot:robot-a"),
            ("acknowledge", "acknowledged", "nurse:nina"),
        ]

    card.get_by_role("button", name="Resolve…").click()
    dialog = page.get_by_role("dialog", name="Resolve alarm")
    dialog.get_by_label("False alarm").check()
    dialog.get_by_label("Sitting down").check()
    dialog.get_by_label("Comment (optional)").fill("sat down on a bench")
    dialog.get_by_role("button", name="Resolve").click()
    expect(dialog).to_have_count(0)
    expect(_card(page, alarm_id)).to_have_count(0)

    with db() as session:
        alarm = session.get(Alarm, alarm_id)
        assert (alarm.state, alarm.verdict, alarm.reason) == (
            "resolved",
            "false_alarm",
            "sitting_down",
        )
        span = (
            session.execute(
                select(Frame.index)
                .where(Frame.seq.in_([alarm.first_seq, alarm.last_seq]))
                .order_by(Frame.index)
            )
            .scalars()
            .all()
        )
        segment = session.scalars(
            select(AnnotationSegment).where(AnnotationSegment.alarm_id == alarm_id)
        ).one()
        assert (segment.status, segment.source, segment.label_key) == (
            "pending",
            "nurse_verdict",
            "sitting_down",
        )
        assert (segment.first_frame, segment.last_frame) == (span[0], span[-1])
        assert segment.video_id == alarm.video_id and segment.model_version == "mlp-7"

    page.goto(f"{live_server.base_url}/nurse/alarms/{alarm_id}")
    replay = page.locator("main.replay")
    expect(replay).to_contain_text("mlp-7")
    expect(replay).to_contain_text("alarm level 60%")
    expect(page.locator("canvas.skeleton")).to_be_visible()
    assert int(replay.get_attribute("data-frames")) >= 40
    expect(replay.locator(".frame-info")).to_contain_text("alarm raised")
    # In a nurse's words: no engineer terms on the page as it opens (issue 35) ...
    shown = replay.inner_text()
    for word in ("Threshold", "Delay", "P(emergency)", "delay filter", " ms)"):
        assert word not in shown, f"{word!r} on the nurse's replay page"
    # ... and the numbers one click away.
    page.get_by_text("Technical details").click()
    expect(replay).to_contain_text("threshold 0.60")
    expect(replay).to_contain_text("delay filter fired")
    expect(page.get_by_role("table", name="Audit trail")).to_contain_text("resolve")
    page.screenshot(path=str(SCREENSHOTS / "alarm_replay.png"), full_page=True)

    page.goto(f"{live_server.base_url}/nurse/history")
    rows = page.get_by_role("table", name="Alarms").locator("tbody tr")
    expect(rows).to_have_count(1)
    expect(rows.first).to_contain_text("False alarm (sitting down)")
    page.screenshot(path=str(SCREENSHOTS / "alarm_history.png"), full_page=True)

    page.goto(f"{live_server.base_url}/nurse/fatigue")
    by_model = page.get_by_role("img", name="Share false by model version (n = resolved alarms)")
    expect(by_model.locator("rect")).to_have_count(1)
    expect(by_model).to_contain_text("mlp-7 (n=1, few)")
    sizes = page.get_by_role("table", name="Sample sizes").get_by_test_id("fatigue-row")
    expect(sizes).to_have_count(1)
    expect(sizes.first).to_contain_text("100 % (n=1, few)")
    page.screenshot(path=str(SCREENSHOTS / "alarm_fatigue.png"), full_page=True)


def test_board_reconnects_and_shows_alarms_raised_while_disconnected(live_server, page, db):
    sign_in(page, live_server.base_url)
    board = page.locator("main.board")
    expect(board).to_have_attribute("data-link", "live")
    expect(page.get_by_text("No open alarms.")).to_be_visible()

    live_server.stop()
    expect(board).to_have_attribute("data-link", "disconnected")
    expect(page.get_by_role("alert")).to_contain_text("Disconnected")

    # While the browser is cut off, the robot's alarm is raised (through the alarm service).
    with transaction(db) as session:
        robot = session.get(Robot, "robot-a")
        evidence = DecisionEvidence(seq=None, ts=None)
        alarm, created = service.raise_or_update(session, robot, None, AlarmKind.PAUSE, evidence)
        assert created
        emergency, _ = service.raise_or_update(session, robot, None, AlarmKind.EMERGENCY, evidence)
        service.escalate(session, emergency, utcnow())
        offline, _ = service.raise_or_update(
            session, robot, None, AlarmKind.ROBOT_OFFLINE, evidence
        )
    live_server.start()

    expect(board).to_have_attribute("data-link", "live", timeout=15_000)
    # The disconnection banner is gone; the Emergency's own banner (an alert too) is there.
    expect(page.get_by_role("alert").filter(has_text="Disconnected")).to_have_count(0)
    card = _card(page, alarm.id)
    expect(card).to_be_visible()
    expect(card).to_contain_text("Pause")
    expect(card).to_have_class(re.compile(r"alarm-pause"))
    escalated = _card(page, emergency.id)
    expect(escalated).to_contain_text("Escalated")
    expect(escalated).to_have_class(re.compile(r"alarm-emergency"))
    # Emergency first; the sound stays locked until the nurse starts the shift.
    expect(_card(page).first).to_have_attribute("data-alarm-id", str(emergency.id))
    expect(board).to_have_attribute("data-audio-state", "locked")
    expect(page.get_by_text("Sound is locked")).to_be_visible()
    technical = _card(page, offline.id)
    expect(technical).to_contain_text("Robot offline")
    expect(technical).to_have_class(re.compile(r"alarm-technical"))
    # Triage order: Emergency, then technical, then Pause.
    expect(_card(page).nth(1)).to_have_attribute("data-alarm-id", str(offline.id))
    expect(_card(page).last).to_have_attribute("data-alarm-id", str(alarm.id))
    page.screenshot(path=str(SCREENSHOTS / "nurse_board_kinds.png"), full_page=True)

    # The escalation says to whom it went: the nurse's board was cut off at the time.
    page.goto(f"{live_server.base_url}/nurse/alarms/{emergency.id}")
    trail = page.get_by_role("table", name="Audit trail")
    expect(trail).to_contain_text("escalated to level 1; announced again on every board showing")
    expect(trail).to_contain_text("nobody had a board of this ward open")


def test_detection_degraded_shows_as_a_technical_card_and_leaves_on_recovery(live_server, page):
    from vigil.protocol import DetectionStatus

    sign_in(page, live_server.base_url)
    expect(page.locator("main.board")).to_have_attribute("data-link", "live")
    with SimulatedRobot(live_server.robot_ws_url, "robot-a", ROBOT_TOKEN) as robot:
        robot.start_transport("t-9", patient="P-9", location="lift 1")
        frames = fall_frames(500, time.time() - 5, "t-9")[:5]
        robot.stream(frames[:2])
        robot.send(
            DetectionStatus(
                ts=time.time(),
                transport_id="t-9",
                degraded=True,
                missing_inputs=["depth", "floor"],
                assigned_model="gbt-floor-2",
                running_model="gbt-kp-3",
                reason="depth stream stopped",
            )
        )
        robot.stream(frames[2:4])  # acknowledged: the status before them is committed
        card = page.locator("article.alarm-technical")
        expect(card).to_have_count(1)
        expect(card.locator(".kind")).to_have_text(
            "Detection degraded: no depth/floor measures, running keypoints-only fallback gbt-kp-3"
        )
        expect(card).to_contain_text("depth stream stopped")
        expect(card).to_contain_text("P-9")
        robot.send(
            DetectionStatus(
                ts=time.time() + 1,
                transport_id="t-9",
                degraded=False,
                assigned_model="gbt-floor-2",
                running_model="gbt-floor-2",
            )
        )
        robot.stream(frames[4:])
        expect(card).to_have_count(0)  # cleared: the cause ended


def test_nurse_acknowledges_and_resolves_on_the_replay_page(live_server, page, db):
    sign_in(page, live_server.base_url)
    expect(page.locator("main.board")).to_have_attribute("data-link", "live")
    with SimulatedRobot(live_server.robot_ws_url, "robot-a", ROBOT_TOKEN) as robot:
        robot.start_transport("t-9", patient="P-9", location="lift 2")
        robot.stream(fall_frames(0, time.time() - 5, "t-9"))
    card = _card(page)
    expect(card).to_have_count(1)
    alarm_id = int(card.get_attribute("data-alarm-id"))

    card.get_by_role("link", name="Replay").click()
    replay = page.locator("main.replay")
    expect(replay.locator(".pill.state-open")).to_have_count(1)
    replay.get_by_role("button", name="Acknowledge").click()
    expect(replay.locator(".pill.state-acknowledged")).to_have_count(1)
    expect(page.get_by_role("table", name="Audit trail")).to_contain_text("acknowledge")

    replay.get_by_role("button", name="Resolve…").click()
    dialog = page.get_by_role("dialog", name="Resolve alarm")
    dialog.get_by_label("False alarm").check()
    resolve = dialog.get_by_role("button", name="Resolve")
    expect(resolve).to_be_disabled()
    expect(dialog.get_by_test_id("resolve-hint")).to_contain_text("needs a reason")
    dialog.get_by_label("Bending").check()
    expect(dialog.get_by_test_id("resolve-hint")).to_have_count(0)
    resolve.click()
    expect(dialog).to_have_count(0)
    expect(replay.locator(".pill.state-resolved")).to_have_count(1)
    expect(replay.get_by_role("button", name="Resolve…")).to_have_count(0)
    with db() as session:
        alarm = session.get(Alarm, alarm_id)
        assert (alarm.state, alarm.verdict, alarm.reason) == ("resolved", "false_alarm", "bending")


def test_storage_stall_shows_the_emergency_not_yet_stored_then_the_stored_card(
    tmp_path, frontend_dist, page
):
    """Alarms fail open: with the database write lock held, the Emergency card shows at once
    with a "Not yet stored" badge and the storage-stalled technical card beside it; the nurse
    acknowledges it there and then (issue 32: acting during a stall); after the release the
    stored alarm, acknowledged, takes the card's place (one card) and the technical card
    leaves."""
    from bench.storage_stall import write_lock

    server = LiveServer.create(tmp_path, frontend_dist, storage_stall_seconds="1")
    server.start()
    try:
        sign_in(page, server.base_url)
        expect(page.locator("main.board")).to_have_attribute("data-link", "live")
        with SimulatedRobot(server.robot_ws_url, "robot-a", ROBOT_TOKEN) as robot:
            robot.start_transport("t-5", patient="P-5", location="lift 2")
            frames = fall_frames(0, time.time() - 5, "t-5")
            robot.stream(frames[:5])  # stored: the transport and the first frames
            with write_lock(server.database_url):
                for i in range(5, len(frames), 10):
                    robot.send_batch(frames[i : i + 10])
                unstored = page.locator("article.alarm-emergency[data-stored='false']")
                expect(unstored).to_have_count(1, timeout=2000)
                expect(unstored.locator(".unstored")).to_have_text("Not yet stored")
                expect(unstored).to_contain_text("P-5")
                stalled = page.locator("article.alarm-technical", has_text="Storage stalled")
                expect(stalled).to_have_count(1, timeout=4000)
                # Acknowledged while storage is stalled: on the board at once.
                unstored.get_by_role("button", name="Acknowledge").click()
                expect(unstored).to_have_attribute("data-state", "acknowledged", timeout=2000)
                expect(unstored).to_contain_text("by nina")
            robot.wait_ack(frames[-1].seq)
        cards = page.locator("article.alarm-emergency")
        expect(cards).to_have_count(1)
        expect(cards).to_have_attribute("data-stored", "true")
        expect(cards.locator(".unstored")).to_have_count(0)
        assert int(cards.get_attribute("data-alarm-id")) > 0
        # Stored, with the acknowledgement made during the stall applied.
        expect(cards).to_have_attribute("data-state", "acknowledged")
        expect(cards.get_by_role("button", name="Acknowledge")).to_have_count(0)
        expect(stalled).to_have_count(0)
    finally:
        server.stop()


def test_audio_pause_silences_for_now_and_lifts_for_a_new_emergency(live_server, page):
    sign_in(page, live_server.base_url)
    board = page.locator("main.board")
    expect(board).to_have_attribute("data-link", "live")
    page.get_by_role("button", name="Start shift").click()
    expect(board).to_have_attribute("data-audio-state", "ready")
    with SimulatedRobot(live_server.robot_ws_url, "robot-a", ROBOT_TOKEN) as robot:
        robot.start_transport("t-p1", patient="P-1", location="lift 1")
        robot.stream(fall_frames(0, time.time() - 5, "t-p1"))
    expect(board).to_have_attribute("data-audio-state", "playing")

    page.get_by_role("button", name="Pause audio 2 min").click()
    expect(board).to_have_attribute("data-audio-state", "ready")
    expect(page.get_by_test_id("audio-paused")).to_contain_text(
        re.compile(r"Audio paused: [12]:\d\d")
    )
    expect(_card(page)).to_have_count(1)  # the visual alarm stays

    with SimulatedRobot(live_server.robot_ws_url, "robot-a", ROBOT_TOKEN) as robot:
        robot.start_transport("t-p2", patient="P-2", location="lift 2")
        robot.stream(fall_frames(1000, time.time() - 5, "t-p2"))
    expect(_card(page)).to_have_count(2)
    expect(board).to_have_attribute("data-audio-state", "playing")  # a new Emergency: pause lifted
    expect(page.get_by_test_id("audio-paused")).to_have_count(0)


def test_triage_order_missed_state_banner_filters_and_handover_export(live_server, page, db):
    """Issue 21: what needs a person now comes first and the newest Emergency is the first card
    and named in the banner; a missed Emergency is latched in its own group and says its
    transport ended; the handover exports the shift as CSV. Issue 32: a missed Emergency nobody
    answered keeps the tone and the banner, also after the nurse acknowledges the new ones."""
    now = utcnow()
    with transaction(db) as session:
        robot = session.get(Robot, "robot-a")
        nina = session.scalars(select(User).where(User.username == "nina")).one()
        ids = {}
        # Ended transports: the monitor raises no robot-offline alarm for them.
        for name, ended in (
            ("t-missed", now - timedelta(minutes=40)),
            ("t-acked", now - timedelta(seconds=20)),
            ("t-pause", now - timedelta(seconds=20)),
        ):
            session.add(
                Transport(
                    id=name,
                    robot_id="robot-a",
                    mode="walking",
                    patient=f"P-{name}",
                    location="corridor C",
                    started_at=now - timedelta(hours=1),
                    ended_at=ended,
                )
            )
        session.flush()
        evidence = DecisionEvidence(seq=None, ts=None)
        for name, kind in (
            ("t-missed", AlarmKind.EMERGENCY),
            ("t-acked", AlarmKind.EMERGENCY),
            ("t-pause", AlarmKind.PAUSE),
        ):
            alarm, _ = service.raise_or_update(
                session, robot, session.get(Transport, name), kind, evidence
            )
            ids[name] = alarm.id
        missed = session.get(Alarm, ids["t-missed"])
        for _ in range(3):
            service.escalate(session, missed, utcnow())
        service.miss(session, missed, utcnow())
        service.escalate_missed(session, missed, utcnow(), "charge nurse")
        service.acknowledge(session, session.get(Alarm, ids["t-acked"]), nina)

    sign_in(page, live_server.base_url)
    board = page.locator("main.board")
    expect(board).to_have_attribute("data-link", "live")
    page.get_by_role("button", name="Start shift").click()
    # A missed Emergency is unanswered: it sounds and holds the banner on its own.
    expect(board).to_have_attribute("data-audio-state", "playing")
    expect(page.get_by_test_id("emergency-banner")).to_have_attribute(
        "data-alarm-id-banner", str(ids["t-missed"])
    )
    expect(page.get_by_test_id("banner-waiting")).to_contain_text("missed")
    expect(_card(page)).to_have_count(3)

    with SimulatedRobot(live_server.robot_ws_url, "robot-a", ROBOT_TOKEN) as robot:
        robot.start_transport("t-new", patient="P-NEW", location="lift lobby")
        frames = fall_frames(0, time.time() - 5, "t-new")
        robot.stream(frames)
        robot.send(TransportEnd(transport_id="t-new", ts=time.time()))
        robot.send_batch(frames[-1:])  # a replay, acknowledged once the end is stored
        robot.wait_ack(frames[-1].seq)
    expect(_card(page)).to_have_count(4)
    new_id = int(_card(page).first.get_attribute("data-alarm-id"))
    order = [int(_card(page).nth(i).get_attribute("data-alarm-id")) for i in range(4)]
    assert order == [new_id, ids["t-pause"], ids["t-missed"], ids["t-acked"]]
    groups = page.locator("section.alarm-group")
    expect(groups).to_have_count(3)
    expect(groups.nth(1)).to_contain_text("Missed: needs review")
    expect(board).to_have_attribute("data-audio-state", "playing")

    banner = page.get_by_test_id("emergency-banner")
    for text in ("robot-a", "P-NEW", "lift lobby"):
        expect(banner).to_contain_text(text)
    expect(page.get_by_test_id("banner-waiting")).to_contain_text(
        re.compile(r"2 Emergencies unanswered, 1 missed, oldest .+ ago")
    )
    missed_card = _card(page, ids["t-missed"])
    expect(missed_card).to_have_attribute("data-state", "missed")
    expect(missed_card).to_contain_text("Missed: needs review")
    expect(missed_card).to_contain_text("Transport ended 40 min ago")
    expect(missed_card.get_by_test_id("escalated-to")).to_have_text("Escalated to charge nurse")
    expect(page.get_by_test_id("board-counts")).to_contain_text(
        "2 need attention · 1 missed · 1 acknowledged"
    )

    # Filters and the compact list.
    page.get_by_label("State").select_option("missed")
    expect(_card(page)).to_have_count(1)
    expect(_card(page).first).to_have_attribute("data-alarm-id", str(ids["t-missed"]))
    page.get_by_label("State").select_option("")
    page.get_by_label("Robot").select_option("robot-a")
    page.get_by_role("button", name="List").click()
    rows = page.locator("main.board [role='row'][data-alarm-id]")
    expect(rows).to_have_count(4)
    expect(rows.first).to_have_attribute("data-alarm-id", str(new_id))
    expect(page.locator(f"[role='row'][data-alarm-id='{ids['t-missed']}']")).to_contain_text(
        "transport ended 40 min ago"
    )
    page.screenshot(path=str(SCREENSHOTS / "nurse_board_list.png"), full_page=True)

    # Acknowledging the new Emergency leaves the missed one unanswered: banner and tone stay,
    # now naming the missed one (a fall nobody answered is never quieter).
    banner.get_by_role("button", name="Acknowledge").click()
    expect(banner).to_have_attribute("data-alarm-id-banner", str(ids["t-missed"]))
    expect(page.get_by_test_id("banner-waiting")).to_contain_text("missed")
    expect(board).to_have_attribute("data-audio-state", "playing")
    expect(rows.first).to_have_attribute("data-alarm-id", str(ids["t-pause"]))

    page.get_by_role("link", name="Handover").click()
    counts = page.get_by_test_id("handover-counts")
    expect(counts).to_contain_text("1missed: needs review")
    expect(page.get_by_role("region", name="Missed: needs review")).to_contain_text(
        f"Emergency #{ids['t-missed']}"
    )
    page.screenshot(path=str(SCREENSHOTS / "shift_handover.png"), full_page=True)
    with page.expect_download() as download:
        page.get_by_role("button", name="Export CSV").click()
    assert download.value.suggested_filename.startswith("handover-ward-a-")
    text = Path(download.value.path()).read_text(encoding="utf-8")
    rows = list(csv.reader(io.StringIO(text)))
    header = rows[2]
    by_id = {int(r[header.index("alarm_id")]): dict(zip(header, r, strict=True)) for r in rows[3:]}
    assert set(by_id) == {new_id, *ids.values()}
    assert by_id[ids["t-missed"]]["section"] == "missed"
    assert by_id[ids["t-missed"]]["was_missed"] == "yes"
    assert by_id[ids["t-missed"]]["transport_ended_at"] != ""
    assert by_id[new_id]["state"] == "acknowledged"
    assert by_id[new_id]["acknowledged_by"] == "nina"

    # A missed alarm is acknowledged from its replay page as from the board; then, with every
    # Emergency answered, banner and tone go.
    page.goto(f"{live_server.base_url}/nurse/alarms/{ids['t-missed']}")
    page.locator("main.replay").get_by_role("button", name="Acknowledge").click()
    expect(page.locator("main.replay .replay-actions .ack")).to_have_count(0)
    page.get_by_role("link", name="Alarms", exact=True).click()
    board = page.locator("main.board")
    expect(_card(page, ids["t-missed"])).to_have_attribute("data-state", "acknowledged")
    expect(page.get_by_test_id("emergency-banner")).to_have_count(0)
    expect(board).not_to_have_attribute("data-audio-state", "playing")


def test_list_of_hundreds_of_alarms_is_in_triage_order_and_draws_the_rows_in_view(
    live_server, page, db
):
    """Issue 21 under load: 300 unresolved alarms (GENERATED rows). The list holds all of them
    in triage order, newest first in each group, as the nurse reads them by scrolling; the page
    draws only the rows near the window; the banner's Emergency is the first row."""
    now = utcnow()
    with transaction(db) as session:
        robot = session.get(Robot, "robot-a")
        nina = session.scalars(select(User).where(User.username == "nina")).one()
        evidence = DecisionEvidence(seq=None, ts=None)
        for i in range(300):
            transport = Transport(
                id=f"t-{i}",
                robot_id="robot-a",
                mode="walking",
                patient=f"GEN-{i}",
                location="generated corridor",
                started_at=now - timedelta(hours=3),
                ended_at=now,
            )
            session.add(transport)
            session.flush()
            alarm, _ = service.raise_or_update(
                session, robot, transport, AlarmKind.EMERGENCY, evidence
            )
            alarm.raised_at = now - timedelta(seconds=300 - i)  # t-299 is the newest
            if i % 3 == 0:
                service.acknowledge(session, alarm, nina)
            elif i != 299:
                service.miss(session, alarm, now)
    sign_in(page, live_server.base_url)
    board = page.locator("main.board")
    expect(board).to_have_attribute("data-link", "live")
    expect(board).to_have_attribute("data-view", "list")
    expect(page.locator(".alarm-list")).to_have_attribute("data-alarm-count", "300")
    drawn = page.locator("main.board .alarm-list [data-alarm-id]")
    assert 0 < drawn.count() < 60  # the rows near the window, not 300

    with db() as session:
        alarms = {a.transport_id: a for a in session.scalars(select(Alarm)).unique()}
    newest = alarms["t-299"].id
    expect(drawn.first).to_have_attribute("data-alarm-id", str(newest))
    expect(page.get_by_test_id("emergency-banner")).to_contain_text("GEN-299")
    missed = [alarms[f"t-{i}"].id for i in range(298, -1, -1) if i % 3 and i != 299]
    acknowledged = [alarms[f"t-{i}"].id for i in range(299, -1, -1) if i % 3 == 0]
    assert list_alarm_ids(page) == [newest, *missed, *acknowledged]
    # Read from the top again after the scroll: the same first row.
    expect(drawn.first).to_have_attribute("data-alarm-id", str(newest))

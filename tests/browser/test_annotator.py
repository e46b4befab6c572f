"""Labelling in Debian Chromium against the real backend: an annotator labels the URFD fall-01
stages with the keyboard and submits, another annotator reviews, the export holds those ranges."""

from __future__ import annotations

import csv
import io

import numpy as np
import pytest
from playwright.sync_api import expect
from sqlalchemy import select

from backend.db import transaction
from backend.labelling.importers.urfd import import_urfd
from backend.models import AnnotationSegment, Role, User, Video
from tests.support.passwords import password_hash
from vigil.datasets import urfd
from vigil.segments import label_runs

from .live_server import PASSWORD, SCREENSHOTS, sign_in

pytestmark = pytest.mark.browser

QUICK = {"walking": "1", "falling": "4", "lying_on_floor": "6"}  # QUICK_LABELS.walking order


def _official_stages() -> list[tuple[int, int, str]]:
    """The fall stages of fall-01 as the URFD authors labelled them (-1, 0, 1)."""
    sequence = urfd.load(urfd.default_dir(), ["fall-01"])[0]
    names = {-1: "walking", 0: "falling", 1: "lying_on_floor"}
    return label_runs([names[int(v)] for v in sequence.urfd_label if not np.isnan(v)])


def _go_to(page, current: int, target: int) -> int:
    delta = target - current
    key = "ArrowRight" if delta > 0 else "ArrowLeft"
    for _ in range(abs(delta) // 10):
        page.keyboard.press(f"Shift+{key}")
    for _ in range(abs(delta) % 10):
        page.keyboard.press(key)
    expect(page.get_by_test_id("frame-counter")).to_contain_text(f"frame {target} /")
    return target


def test_annotator_labels_fall_stages_reviewer_accepts_export_matches(live_server, page, db):
    SCREENSHOTS.mkdir(parents=True, exist_ok=True)
    with transaction(db) as session:
        import_urfd(session, urfd.default_dir(), ["fall-01"], labels=False)
        session.add(
            User(username="rita", password_hash=password_hash(PASSWORD), role=Role.ANNOTATOR)
        )
    with db() as session:
        video_id = session.scalars(select(Video.id).where(Video.name == "fall-01")).one()
    stages = _official_stages()
    assert [s[2] for s in stages] == ["walking", "falling", "lying_on_floor"]

    sign_in(page, live_server.base_url, "anna")
    expect(page).to_have_url(f"{live_server.base_url}/annotate")
    page.get_by_role("link", name="fall-01").click()
    expect(page.get_by_test_id("frame-counter")).to_contain_text("frame 0 / 159")
    expect(page.locator("[data-testid=player] img")).to_be_visible()

    frame = 0
    segments = page.locator("[data-testid=segment]")
    for first, last, label in stages:
        frame = _go_to(page, frame, first)
        page.keyboard.press("i")
        frame = _go_to(page, frame, last)
        page.keyboard.press("o")
        page.keyboard.press(QUICK[label])
        expect(page.locator(f"[data-testid=segment][data-label={label}]")).to_have_count(1)
    expect(segments).to_have_count(3)

    # Undo takes the last segment back, redo restores it (under a new id on the server).
    page.keyboard.press("Control+z")
    expect(segments).to_have_count(2)
    page.keyboard.press("Control+Shift+z")
    expect(segments).to_have_count(3)
    shown = sorted(
        (
            int(s.get_attribute("data-first")),
            int(s.get_attribute("data-last")),
            s.get_attribute("data-label"),
        )
        for s in segments.all()
    )
    assert shown == sorted(stages)

    # Playback: faster with ], space plays and pauses; V switches to skeleton only.
    page.keyboard.press("]")
    page.keyboard.press("]")
    expect(page.get_by_test_id("speed")).to_have_text("4x")
    page.keyboard.press("Home")
    page.keyboard.press(" ")
    expect(page.get_by_test_id("frame-counter")).not_to_contain_text("frame 0 /")
    page.keyboard.press(" ")
    page.keyboard.press("v")
    expect(page.locator("[data-testid=player] img")).to_have_count(0)
    page.keyboard.press("v")
    frame = 0
    page.keyboard.press("Home")

    page.keyboard.press("?")
    expect(page.get_by_role("dialog", name="Keyboard shortcuts")).to_be_visible()
    page.keyboard.press("Escape")
    _go_to(page, frame, 90)  # mid-fall, and one of the frames with a depth picture (colours)
    page.wait_for_load_state("networkidle")
    page.locator(".label-main").screenshot(path=str(SCREENSHOTS / "annotator_player.png"))
    page.get_by_test_id("timeline").screenshot(path=str(SCREENSHOTS / "annotator_timeline.png"))

    page.keyboard.press("Control+Enter")
    expect(page.get_by_test_id("status")).to_contain_text("Submitted 3 segment(s)")
    expect(page.locator("[data-testid=segment][data-status=submitted]")).to_have_count(3)

    # Nobody reviews their own segments: the queue shows anna's rows without Accept or Reject.
    page.goto(f"{live_server.base_url}/annotate")
    page.get_by_role("link", name="Review queue").click()
    expect(page.get_by_test_id("queue-row")).to_have_count(3)
    expect(page.get_by_test_id("own-segment")).to_have_count(3)
    expect(page.get_by_role("button", name="Accept")).to_have_count(0)

    page.get_by_role("button", name="Sign out").click()
    sign_in(page, live_server.base_url, "rita")
    expect(page.get_by_text("rita · annotator")).to_be_visible()
    page.goto(f"{live_server.base_url}/annotate")
    page.get_by_role("link", name="Review queue").click()
    rows = page.get_by_test_id("queue-row")
    expect(rows).to_have_count(3)
    for remaining in (2, 1, 0):
        rows.first.get_by_role("button", name="Accept").click()
        expect(rows).to_have_count(remaining)

    response = page.request.get(
        f"{live_server.base_url}/api/labelling/videos/{video_id}/export?format=csv"
    )
    assert response.ok, response.text()
    rows_csv = list(csv.DictReader(io.StringIO(response.text())))
    exported = label_runs([r["label_key"] or None for r in rows_csv])
    assert exported == stages
    with db() as session:
        stored = session.scalars(
            select(AnnotationSegment).where(AnnotationSegment.status == "accepted")
        ).all()
        assert {s.annotator_id for s in stored} != {None}
        assert sorted((s.first_frame, s.last_frame, s.label_key) for s in stored) == sorted(stages)


def test_label_search_applies_only_a_chosen_label_and_overlaps_get_sub_rows(live_server, page, db):
    with transaction(db) as session:
        import_urfd(session, urfd.default_dir(), ["fall-01"], labels=False)
    sign_in(page, live_server.base_url, "anna")
    page.get_by_role("link", name="fall-01").click()
    expect(page.get_by_test_id("frame-counter")).to_contain_text("frame 0 / 159")
    segments = page.locator("[data-testid=segment]")

    frame = 0
    page.keyboard.press("i")
    frame = _go_to(page, frame, 20)
    page.keyboard.press("o")
    page.keyboard.press("/")
    page.keyboard.type("lying")
    expect(page.get_by_test_id("label-matches").get_by_role("button")).to_have_count(2)
    page.keyboard.press("Enter")  # two labels match: Enter alone must not pick one
    expect(page.get_by_test_id("status")).to_contain_text("2 labels match")
    expect(segments).to_have_count(0)
    page.keyboard.press("ArrowDown")
    page.keyboard.press("ArrowDown")
    page.keyboard.press("Enter")
    expect(page.locator("[data-testid=segment][data-label=lying_on_floor]")).to_have_count(1)

    # A second segment overlapping the first goes to its own sub-row instead of covering it.
    frame = _go_to(page, frame, 10)
    page.keyboard.press("i")
    frame = _go_to(page, frame, 30)
    page.keyboard.press("o")
    page.keyboard.press(QUICK["walking"])
    expect(segments).to_have_count(2)
    floor = page.locator("[data-testid=segment][data-label=lying_on_floor]")
    walking = page.locator("[data-testid=segment][data-label=walking]")
    assert floor.get_attribute("data-sub-row") != walking.get_attribute("data-sub-row")
    fills = {
        s.locator("rect").first.get_attribute("fill") for s in (floor, walking)
    }  # each label its own colour
    assert len(fills) == 2


def test_reimporting_an_export_adds_nothing_and_says_so(live_server, page, db):
    with transaction(db) as session:
        import_urfd(session, urfd.default_dir(), ["fall-01"])  # with URFD's own labels
    sign_in(page, live_server.base_url, "anna")
    expect(page).to_have_url(f"{live_server.base_url}/annotate")
    with db() as session:
        video_id = session.scalars(select(Video.id).where(Video.name == "fall-01")).one()
    exported = page.request.get(
        f"{live_server.base_url}/api/labelling/videos/{video_id}/export?format=csv"
    )
    assert exported.ok and "fall-01.csv" in exported.headers["content-disposition"]
    search = page.get_by_label("Search videos")
    search.fill("adl")
    expect(page.get_by_test_id("video-count")).to_have_text("0 of 1 videos")
    search.fill("fall 01")
    expect(page.get_by_test_id("video-count")).to_have_text("1 of 1 videos")
    form = page.get_by_role("form", name="Import")
    form.locator("input[type=file]").set_input_files(
        {"name": "fall-01.csv", "mimeType": "text/csv", "buffer": exported.body()}
    )
    form.get_by_label("Format").select_option("csv")
    form.get_by_role("button", name="Import", exact=True).click()
    expect(form.get_by_role("status")).to_contain_text(
        "Imported into fall-01: 0 new segment(s), 3 already there"
    )
    with db() as session:
        count = len(session.scalars(select(AnnotationSegment)).all())
    assert count == 3

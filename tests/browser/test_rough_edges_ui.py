"""Rough edges of issue 35 in the engineer's and annotator's pages, in Debian Chromium against
the real backend: a shadow run and a rollback each wait for the engineer's confirmation (a
rollback with the reason they type, then a live row says what the robots run), and the JSON
import into a video that exists already asks in the UI's words, with a button per choice."""

from __future__ import annotations

import json

import pytest
from playwright.sync_api import expect
from sqlalchemy import select

from backend.db import transaction
from backend.labelling.importers.urfd import import_urfd
from backend.models import AnnotationSegment, Deployment, ModelVersion, Robot, Video
from tests.registry_fixtures import trained_model_dir  # noqa: F401
from vigil.datasets import urfd

from .live_server import sign_in
from .test_engineer_console import system  # noqa: F401

pytestmark = pytest.mark.browser


def _start_shadow(page, version: str) -> None:
    page.get_by_role("link", name="Model registry").click()
    page.get_by_role("link", name=version, exact=True).click()
    page.get_by_label("Robot", exact=True).select_option("robot-a")
    page.get_by_role("button", name="Run in shadow mode").click()
    dialog = page.get_by_role("dialog", name="Confirm shadow run")
    expect(dialog).to_contain_text(f"Run {version} in shadow mode on robot robot-a: 1 robot")
    dialog.get_by_role("button", name="Start the shadow run").click()
    expect(page.get_by_role("status")).to_contain_text("active (shadow)")


def test_shadow_start_and_rollback_ask_first(system, page):  # noqa: F811
    server, factory = system
    with transaction(factory) as session:  # the test models need floor measures
        session.get(Robot, "robot-a").inputs = ["keypoints", "depth", "floor"]
    sign_in(page, server.base_url, "erin")
    page.get_by_role("link", name="rf-test-1").click()
    page.get_by_label("Robot", exact=True).select_option("robot-a")

    # Shadow start: nothing happens before the engineer confirms; Back changes nothing.
    page.get_by_role("button", name="Run in shadow mode").click()
    dialog = page.get_by_role("dialog", name="Confirm shadow run")
    expect(dialog).to_be_visible()
    with factory() as session:
        assert session.scalars(select(Deployment)).all() == []
    dialog.get_by_role("button", name="Back", exact=True).click()
    expect(dialog).to_have_count(0)
    with factory() as session:
        assert session.scalars(select(Deployment)).all() == []
    _start_shadow(page, "rf-test-1")
    _start_shadow(page, "blind-1")  # supersedes the first shadow run on robot-a
    with factory() as session:
        ids = dict(session.execute(select(ModelVersion.version, ModelVersion.id)).all())
        assert session.get(Robot, "robot-a").shadow_model_id == ids["blind-1"]

    # Rollback: asks first, with a reason the engineer must type.
    page.get_by_role("link", name="Fleet & deployments").click()
    deployments = page.get_by_role("table", name="Deployments")
    blind = deployments.get_by_role("row").filter(has_text="blind-1 (shadow)")
    expect(blind).to_contain_text("active")
    blind.get_by_role("button", name="Roll back").click()
    confirm = page.get_by_role("dialog", name="Confirm rollback")
    expect(confirm).to_contain_text("blind-1 (shadow) on robot-a?")
    expect(confirm.get_by_role("button", name="Confirm rollback")).to_be_disabled()
    confirm.get_by_label("Reason").fill("   ")
    expect(confirm.get_by_role("button", name="Confirm rollback")).to_be_disabled()
    confirm.get_by_role("button", name="Back", exact=True).click()
    expect(confirm).to_have_count(0)
    with factory() as session:
        assert session.get(Robot, "robot-a").shadow_model_id == ids["blind-1"]
    blind.get_by_role("button", name="Roll back").click()
    expect(confirm.get_by_label("Reason")).to_have_value("")  # a fresh reason each time
    confirm.get_by_label("Reason").fill("disagrees on every fall")
    confirm.get_by_role("button", name="Confirm rollback").click()
    expect(confirm).to_have_count(0)
    expect(blind).to_contain_text("rolled_back")
    expect(blind).to_contain_text("disagrees on every fall (erin)")

    # A live row says what robot-a runs in shadow now.
    live = deployments.get_by_role("row").filter(has_text="restored by the rollback")
    expect(live).to_have_count(1)
    expect(live).to_contain_text("rf-test-1 (shadow)")
    expect(live).to_contain_text("active")
    expect(live).to_contain_text("robot-a")
    expect(live).to_contain_text("disagrees on every fall (erin)")
    with factory() as session:
        assert session.get(Robot, "robot-a").shadow_model_id == ids["rf-test-1"]
        rolled = session.scalars(
            select(Deployment).where(Deployment.model_version_id == ids["blind-1"])
        ).one()
        assert rolled.rollback_reason == "disagrees on every fall (erin)"


def test_json_import_into_an_existing_video_asks_merge_or_replace(live_server, page, db):
    with transaction(db) as session:
        import_urfd(session, urfd.default_dir(), ["fall-01"])  # with URFD's own labels
    sign_in(page, live_server.base_url, "anna")
    expect(page).to_have_url(f"{live_server.base_url}/annotate")
    with db() as session:
        video_id = session.scalars(select(Video.id).where(Video.name == "fall-01")).one()
    exported = page.request.get(
        f"{live_server.base_url}/api/labelling/videos/{video_id}/export?format=json"
    )
    assert exported.ok
    document = exported.json()
    document["segments"].append(  # one label the video lacks
        {**document["segments"][0], "last_frame": document["segments"][0]["first_frame"]}
    )
    form = page.get_by_role("form", name="Import")
    form.locator("input[type=file]").set_input_files(
        {
            "name": "fall-01.json",
            "mimeType": "application/json",
            "buffer": json.dumps(document).encode(),
        }
    )
    form.get_by_role("button", name="Import", exact=True).click()  # JSON, a new video: refused

    ask = page.get_by_role("dialog", name="Video already labelled")
    expect(ask).to_contain_text(
        "This video already has labels. Merge the imported labels with them, or replace them?"
    )
    expect(page.get_by_text("mode=merge")).to_have_count(0)  # not in the API's words
    expect(page.get_by_role("alert")).to_have_count(0)
    expect(ask.get_by_role("button", name="Replace")).to_be_visible()
    ask.get_by_role("button", name="Merge").click()  # the same file again, mode=merge
    expect(form.get_by_role("status")).to_contain_text(
        "Imported into fall-01: 1 new segment(s), 3 already there"
    )
    expect(ask).to_have_count(0)
    with db() as session:
        assert len(session.scalars(select(AnnotationSegment)).all()) == 4
        assert len(session.scalars(select(Video)).all()) == 1

    # Replace: the imported labels still under review are withdrawn first, then imported again.
    form.locator("input[type=file]").set_input_files(
        {
            "name": "fall-01.json",
            "mimeType": "application/json",
            "buffer": json.dumps(document).encode(),
        }
    )
    form.get_by_role("button", name="Import", exact=True).click()
    ask.get_by_role("button", name="Replace").click()
    expect(form.get_by_role("status")).to_contain_text(
        "1 imported segment(s) under review replaced"
    )

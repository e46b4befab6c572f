"""Cross-site request forgery: cookie-authenticated writes must come from this site (Origin or
Sec-Fetch-Site), else 403 with a message. Security headers on every response."""

from __future__ import annotations

from sqlalchemy import select

from backend.deps import SESSION_COOKIE
from backend.models import Alarm, AlarmState, Role
from tests.backend.conftest import ROBOT_TOKEN
from tests.backend.test_alarm_lifecycle import stream
from tests.backend.test_first_alarm import frame

FORM = {"Content-Type": "application/x-www-form-urlencoded"}


def test_an_empty_cross_site_form_post_with_the_cookie_does_not_acknowledge(
    client, robot, make_account, session_factory
):
    nurse = make_account(Role.NURSE, ward="ward-a")
    stream(client, robot, ROBOT_TOKEN, "t-a", frame(0, "emergency", "t-a"))
    with session_factory() as session:
        alarm = session.scalars(select(Alarm)).one()
    client.cookies.set(SESSION_COOKIE, nurse.token)
    url = f"/api/alarms/{alarm.id}/acknowledge"
    for headers in (
        {"Origin": "https://evil.example", "Sec-Fetch-Site": "cross-site"},
        {"Origin": "https://evil.example"},
        {"Sec-Fetch-Site": "same-site"},
        {"Origin": "null"},
        {},  # neither header: not known to come from this site
    ):
        response = client.post(url, content=b"", headers={**FORM, **headers})
        assert response.status_code == 403, (headers, response.text)
        assert "refused" in response.json()["detail"]
    with session_factory() as session:
        assert session.get(Alarm, alarm.id).state == AlarmState.OPEN

    same_site = client.post(url, json={}, headers={"Origin": "http://testserver"})
    assert same_site.status_code == 200, same_site.text
    assert same_site.json()["state"] == "acknowledged"


def test_same_origin_fetch_and_bearer_writes_pass(client, make_account):
    nurse = make_account(Role.NURSE)
    client.cookies.set(SESSION_COOKIE, nurse.token)
    fetch = {"Sec-Fetch-Site": "same-origin", "Origin": "http://testserver"}
    assert client.post("/api/auth/logout", headers=fetch).status_code == 204
    client.cookies.clear()
    other = make_account(Role.NURSE, username="nina")
    # A bearer token is never attached by the browser on its own: no Origin needed.
    assert client.post("/api/auth/logout", headers=other.headers).status_code == 204


def test_a_cross_site_login_form_is_refused(client):
    response = client.post(
        "/api/auth/login",
        data={"username": "a", "password": "b"},
        headers={**FORM, "Sec-Fetch-Site": "cross-site"},
    )
    assert response.status_code == 403


def test_security_headers_on_api_and_page_responses(client):
    for response in (client.get("/api/health"), client.get("/"), client.get("/api/nothing")):
        assert response.headers["x-frame-options"] == "DENY"
        assert response.headers["x-content-type-options"] == "nosniff"
        csp = response.headers["content-security-policy"]
        assert "script-src 'self'" in csp and "frame-ancestors 'none'" in csp
        assert "unsafe-inline" not in csp

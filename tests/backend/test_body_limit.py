"""Uploads are capped while they stream: 413 naming the limit, and nothing past the limit is
read (the import used to read a 200 MB file whole before refusing it)."""

from __future__ import annotations

import asyncio
import json

from backend.body_limit import BodySizeLimit
from backend.models import Role
from backend.settings import Settings

CHUNK = 1024


def run_limited(limit: int, headers: list[tuple[bytes, bytes]]) -> tuple[int, int, dict]:
    """An app that reads its whole body, behind the middleware, fed an endless body in 1 KiB
    chunks; returns (chunks pulled from the server, status, response body)."""
    pulled = 0
    sent: list[dict] = []

    async def endless_body() -> dict:
        nonlocal pulled
        pulled += 1
        return {"type": "http.request", "body": b"x" * CHUNK, "more_body": True}

    async def send(message: dict) -> None:
        sent.append(message)

    async def reads_everything(scope, receive, send) -> None:
        while (await receive())["more_body"]:
            pass

    settings = Settings(secret_key="x", max_upload_bytes=limit)
    scope = {"type": "http", "method": "POST", "path": "/", "headers": headers}
    asyncio.run(BodySizeLimit(reads_everything, settings)(scope, endless_body, send))
    start = next(m for m in sent if m["type"] == "http.response.start")
    body = b"".join(m.get("body", b"") for m in sent if m["type"] == "http.response.body")
    return pulled, start["status"], json.loads(body)


def test_a_streamed_body_is_refused_once_it_passes_the_limit_and_read_no_further():
    pulled, status, body = run_limited(10 * CHUNK, headers=[])
    assert status == 413
    assert pulled == 11  # the chunk that crossed the limit, and not one more
    assert body["detail"] == (
        "request body larger than 10240 bytes (the limit, VIGIL_MAX_UPLOAD_BYTES)"
    )


def test_a_declared_length_above_the_limit_is_refused_before_reading():
    pulled, status, body = run_limited(64 * 2**20, headers=[(b"content-length", b"209715200")])
    assert (pulled, status) == (0, 413)
    assert "64 MiB" in body["detail"]


def test_the_default_limit_is_64_mib():
    assert Settings(secret_key="x").max_upload_bytes == 64 * 2**20


def test_import_larger_than_the_limit_gets_413_and_smaller_is_still_read(client, make_account):
    client.app.state.services.settings.max_upload_bytes = 20_000
    annotator = make_account(Role.ANNOTATOR, None, "anna")
    big = b'{"format": "vigil-labels", "pad": "' + b"x" * 30_000 + b'"}'
    for content in (big, iter([big[:10_000], big[10_000:]])):  # declared length, then chunked
        if isinstance(content, bytes):
            response = client.post(
                "/api/labelling/import?format=json",
                files={"file": ("big.json", content)},
                headers=annotator.headers,
            )
        else:
            response = client.post(
                "/api/labelling/import?format=json",
                content=content,
                headers={**annotator.headers, "content-type": "multipart/form-data; boundary=b"},
            )
        assert response.status_code == 413, response.text
        assert "VIGIL_MAX_UPLOAD_BYTES" in response.json()["detail"]
    small = client.post(
        "/api/labelling/import?format=json",
        files={"file": ("small.json", b"{}")},
        headers=annotator.headers,
    )
    assert small.status_code == 422 and small.json()["detail"].startswith("format")

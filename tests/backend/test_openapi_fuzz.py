"""Schemathesis against the OpenAPI of the real backend (uvicorn subprocess), after hostile
imports have been tried: generated requests to every operation, as each role, never get a 5xx
and never lose their connection.

A few examples per operation and role keep the default run short; set VIGIL_FUZZ_EXAMPLES for
a deeper run (e.g. 50)."""

from __future__ import annotations

import json
import os
from urllib.parse import unquote

import numpy as np
import pytest
import requests
import schemathesis
from hypothesis import HealthCheck, given, settings

from backend.db import transaction
from backend.models import Role, User
from backend.process import BackendProcess, free_port
from backend.security import create_access_token
from tests.backend.conftest import SUBPROCESS_SECRET
from tests.backend.test_reliability import backend_env  # noqa: F401  (fixture)
from tests.support.passwords import password_hash
from vigil.skeleton import N_FLOOR, N_KEYPOINTS

EXAMPLES_PER_OPERATION = int(os.environ.get("VIGIL_FUZZ_EXAMPLES", "3"))  # per role
UPLOAD_LIMIT = 1_000_000  # VIGIL_MAX_UPLOAD_BYTES of the fuzzed backend
EMOJI_NAME = 'fall 🚑 "01"'
DEPTH_NAME = "with-depth-and-intrinsics"


def vigil_json(name: str, frames: int = 12, **video) -> dict:
    """A small valid Vigil JSON export: keypoints, depth and floor on every frame."""
    rng = np.random.default_rng(7)
    keypoints = rng.uniform(50, 400, (frames, N_KEYPOINTS, 3)).round(3)
    keypoints[:, :, 2] = 0.9
    return {
        "format": "vigil-labels",
        "version": 1,
        "video": {"name": name, "mode": "walking", "fps": 30.0, **video},
        "frames": [
            {
                "index": i,
                "ts": i / 30,
                "keypoints": keypoints[i].tolist(),
                "depth": [2.0 + 0.01 * j for j in range(N_KEYPOINTS)],
                "floor": [0.1] * N_FLOOR,
            }
            for i in range(frames)
        ],
        "segments": [{"first_frame": 0, "last_frame": frames - 1, "label_key": "walking"}],
    }


def with_video(**changes) -> str:
    document = vigil_json("hostile")
    document["video"].update(changes)
    return json.dumps(document)


INTRINSICS = {"fx": 525.0, "fy": 525.0, "cx": 319.5, "cy": 239.5}
# (what, format, name parameter, file content, expected status)
HOSTILE_IMPORTS = [
    ("fps NaN", "json", None, with_video(fps=12345.5).replace("12345.5", "NaN"), 422),
    ("fps inf", "json", None, with_video(fps=12345.5).replace("12345.5", "1e999"), 422),
    ("image_width abc", "json", None, with_video(image_width="abc"), 422),
    ("camera list", "json", None, with_video(camera=["a", "b"]), 422),
    ("intrinsics string", "json", None, with_video(intrinsics="525,525,319.5,239.5"), 422),
    ("name CR/LF in file", "json", None, with_video(name="a\r\nSet-Cookie: x=1"), 422),
    ("name CR/LF param", "json", "b\r\nX: 1", with_video(), 422),
    ("not UTF-8", "csv", None, b"\xff\xfe\x00video", 422),
    ("csv garbage", "csv", None, 'video,frame\x00\n"', 422),
    (
        "coco image id list",
        "coco",
        "coco-hostile",
        json.dumps({"info": {"video": {}}, "images": [{"id": [1]}]}),
        422,
    ),
    ("over the size limit", "json", "huge", b"{" + b" " * (3 * UPLOAD_LIMIT) + b"}", 413),
    ("emoji name", "json", None, json.dumps(vigil_json(EMOJI_NAME)), 201),
    (
        "depth and intrinsics",
        "json",
        None,
        json.dumps(
            vigil_json(DEPTH_NAME, intrinsics=INTRINSICS, image_width=640, image_height=480)
        ),
        201,
    ),
]


def attempt_hostile_imports(base: str, headers: dict) -> list[str]:
    problems = []
    for what, fmt, name, content, expected in HOSTILE_IMPORTS:
        body = content.encode() if isinstance(content, str) else content
        params = {"format": fmt} | ({"name": name} if name else {})
        try:
            response = requests.post(
                f"{base}/api/labelling/import",
                params=params,
                headers=headers,
                files={"file": ("hostile", body)},
                timeout=30,
            )
        except requests.RequestException as error:
            problems.append(f"import {what}: connection dropped ({error})")
            continue
        if response.status_code != expected:
            problems.append(f"import {what}: {response.status_code} {response.text[:200]}")
    return problems


def use_the_imported_videos(base: str, headers: dict) -> list[str]:
    """What broke later before: export (every format), facets, the 3D view."""
    problems = []
    videos = requests.get(f"{base}/api/labelling/videos", headers=headers, timeout=30).json()
    by_name = {v["name"]: v["id"] for v in videos}
    for fmt, ext in (("csv", "csv"), ("json", "json"), ("coco", "coco.json")):
        response = requests.get(
            f"{base}/api/labelling/videos/{by_name[EMOJI_NAME]}/export",
            params={"format": fmt},
            headers=headers,
            timeout=30,
        )
        disposition = response.headers.get("content-disposition", "")
        if response.status_code != 200 or (
            unquote(disposition.partition("filename*=UTF-8''")[2]) != f"{EMOJI_NAME}.{ext}"
        ):
            problems.append(f"export {fmt}: {response.status_code} {disposition!r}")
    response = requests.post(
        f"{base}/api/labelling/videos/{by_name[DEPTH_NAME]}/view3d",
        params={"frame": 3},
        headers=headers,
        timeout=30,
    )
    if response.status_code != 200 or response.json()["centre_frame"] != 3:
        problems.append(f"view3d: {response.status_code} {response.text[:200]}")
    facets = requests.get(f"{base}/api/labelling/facets", headers=headers, timeout=30)
    if facets.status_code != 200:
        problems.append(f"facets: {facets.status_code} {facets.text[:200]}")
    return problems


def fuzz(operation, base: str, role: Role, headers: dict) -> list[str]:
    """Generated requests to one operation as one role: each 5xx or dropped connection."""
    failures: list[str] = []

    @settings(
        max_examples=EXAMPLES_PER_OPERATION,
        deadline=None,
        database=None,
        suppress_health_check=list(HealthCheck),
    )
    @given(case=operation.as_strategy())
    def check(case) -> None:
        where = f"{role}: {case.method} {case.formatted_path}"
        try:
            response = case.call(base_url=base, headers=headers, timeout=10)
        except requests.RequestException as error:
            failures.append(f"{where} -> connection dropped: {error}")
            return
        if response.status_code >= 500:
            failures.append(f"{where} -> {response.status_code}: {response.text[:200]}")

    check()
    return failures


@pytest.mark.timeout(600)
def test_generated_requests_never_get_a_server_error(
    backend_env,  # noqa: F811
    robot,
    session_factory,
    tmp_path,
):
    tokens = {}
    with transaction(session_factory) as session:
        for role in Role:
            user = User(
                username=f"fuzz-{role}",
                password_hash=password_hash("fuzz-password"),
                role=role,
                ward="ward-a" if role == Role.NURSE else None,
            )
            session.add(user)
            session.flush()
            tokens[role] = create_access_token(SUBPROCESS_SECRET, user.id, 60)
    headers_of = {role: {"Authorization": f"Bearer {token}"} for role, token in tokens.items()}

    env = backend_env | {
        "VIGIL_MAX_UPLOAD_BYTES": str(UPLOAD_LIMIT),
        "VIGIL_VISER_PORT": str(free_port()),  # the 3D view, never a port shared with others
    }
    failures: list[str] = []
    with BackendProcess(env, log_path=tmp_path / "backend.log") as server:
        failures += attempt_hostile_imports(server.http, headers_of[Role.ADMIN])
        failures += use_the_imported_videos(server.http, headers_of[Role.ADMIN])
        schema = schemathesis.openapi.from_url(f"{server.http}/openapi.json")
        operations = [result.ok() for result in schema.get_all_operations()]
        assert len(operations) >= 20
        for role in Role:
            for operation in operations:
                if operation.path.endswith(("/logout", "/token")) and operation.method != "get":
                    continue  # would sign the user out or revoke the test robot mid-run
                failures += fuzz(operation, server.http, role, headers_of[role])
    assert not failures, "\n".join(failures[:20])

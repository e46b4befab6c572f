"""Bad input is refused at the import with a 422 naming the field, before it is stored: every
value a later endpoint reads (export, facets, the 3D view) is of its type, finite, in range."""

from __future__ import annotations

import copy
import json
from urllib.parse import unquote

import pytest

from backend.api.downloads import attachment
from tests.backend.labelling.test_exchange import API, _export, _import


@pytest.fixture
def exported(client, urfd_videos, annotator) -> dict:
    return _export(client, annotator, urfd_videos["fall-01"], "json").json()


def changed(document: dict, path: str, value) -> dict:
    document = copy.deepcopy(document)
    *parents, last = path.split(".")
    target = document
    for part in parents:
        target = target[int(part)] if isinstance(target, list) else target[part]
    if isinstance(target, list):
        target[int(last)] = value
    else:
        target[last] = value
    return document


def as_text(document: dict) -> str:
    """JSON text; an infinity as 1e999, a number too large for a float (Python reads inf)."""
    return json.dumps(document).replace("Infinity", "1e999")


JSON_CASES = [
    pytest.param("video.fps", float("inf"), "video.fps", id="fps-inf"),
    pytest.param("video.fps", "30", "video.fps", id="fps-string"),
    pytest.param("video.fps", 0, "video.fps", id="fps-zero"),
    pytest.param("video.image_width", "abc", "video.image_width", id="width-abc"),
    pytest.param("video.image_height", -480, "video.image_height", id="height-negative"),
    pytest.param("video.camera", ["cam0", "cam1"], "video.camera", id="camera-list"),
    pytest.param("video.location", {"ward": "3a"}, "video.location", id="location-object"),
    pytest.param("video.intrinsics", "525,525,319.5,239.5", "video.intrinsics", id="intr-str"),
    pytest.param(
        "video.intrinsics",
        {"fx": 0, "fy": 525, "cx": 1, "cy": 1},
        "video.intrinsics.fx",
        id="intrinsics-zero-focal",
    ),
    pytest.param("video.intrinsics", {"fx": 525}, "video.intrinsics.fy", id="intrinsics-part"),
    pytest.param("video.generated", "yes", "video.generated", id="generated-string"),
    pytest.param("video.mode", "flying", "video.mode", id="mode-unknown"),
    pytest.param("video.name", "fall\r\nX-Injected: 1", "video.name", id="name-crlf"),
    pytest.param("video.name", "bell\x07", "video.name", id="name-control"),
    pytest.param("video.name", "   ", "video.name", id="name-blank"),
    pytest.param("frames.3.index", "3", "frames[3].index", id="index-string"),
    pytest.param("frames.3.ts", "0.1", "frames[3].ts", id="ts-string"),
    pytest.param("frames.3", [1, 2], "frames[3]", id="frame-not-object"),
    pytest.param("segments", {"first_frame": 0}, "segments", id="segments-object"),
    pytest.param("segments", ["walking"], "segments[0]", id="segment-string"),
    pytest.param(
        "segments",
        [{"first_frame": "0", "last_frame": 5, "label_key": "walking"}],
        "segments[0].first_frame",
        id="segment-frame-string",
    ),
    pytest.param(
        "segments",
        [{"first_frame": 0, "last_frame": 5, "label_key": ["walking"]}],
        "segments[0].label_key",
        id="segment-label-list",
    ),
]


@pytest.mark.parametrize(("path", "value", "field"), JSON_CASES)
def test_json_import_refuses_a_bad_value_naming_the_field(
    client, annotator, exported, path, value, field
):
    document = changed(exported, path, value)
    if path != "video.name":
        document["video"]["name"] = "hostile"
    response = _import(client, annotator, "json", as_text(document))
    assert response.status_code == 422, response.text
    assert response.json()["detail"].startswith(f"{field}:"), response.json()
    names = [v["name"] for v in client.get(f"{API}/videos", headers=annotator.headers).json()]
    assert "hostile" not in names and len(names) == 2  # nothing stored


@pytest.mark.parametrize("constant", ["NaN", "Infinity", "-Infinity"])
def test_nan_and_infinity_are_not_json_numbers(client, annotator, exported, constant):
    text = json.dumps(changed(exported, "video.fps", 12345.5)).replace("12345.5", constant)
    response = _import(client, annotator, "json", text, name="nan-fps")
    assert response.status_code == 422
    assert response.json()["detail"] == f"file: {constant} is not a JSON number"


def test_name_parameter_with_control_characters_is_refused(client, annotator, exported):
    response = client.post(
        f"{API}/import",
        params={"format": "json", "name": "a\nb"},
        files={"file": ("x", json.dumps(exported).encode())},
        headers=annotator.headers,
    )
    assert response.status_code == 422
    assert response.json()["detail"].startswith("name: must not contain control characters")


COCO_CASES = [
    pytest.param("images.0.id", [1], "images[0].id", id="image-id-list"),
    pytest.param("images.0.id", "1", "images[0].id", id="image-id-string"),
    pytest.param("images.0.frame_index", -1, "images[0].frame_index", id="frame-negative"),
    pytest.param("images.1.frame_index", 0, "images", id="frame-twice"),
    pytest.param("images.0", "frame", "images[0]", id="image-string"),
    pytest.param("annotations.0.keypoints.4", "x", "annotations[0].keypoints[4]", id="kp-str"),
    pytest.param("annotations.0.keypoints.4", 1e39, "annotations[0].keypoints[4]", id="kp-big"),
    pytest.param("annotations.0.keypoints", [1.0] * 50, "annotations[0].keypoints", id="kp-50"),
    pytest.param("annotations.0", None, "annotations[0]", id="annotation-null"),
    pytest.param("info.video.camera", ["a"], "video.camera", id="camera-list"),
    pytest.param("info.video.fps", 1e999, "video.fps", id="fps-inf"),
    pytest.param("info", "x", "info", id="info-string"),
]


@pytest.mark.parametrize(("path", "value", "field"), COCO_CASES)
def test_coco_import_refuses_a_bad_value_naming_the_field(
    client, annotator, urfd_videos, path, value, field
):
    document = _export(client, annotator, urfd_videos["fall-01"], "coco").json()
    document = changed(document, path, value)
    response = _import(client, annotator, "coco", as_text(document), name="hostile")
    assert response.status_code == 422, response.text
    assert response.json()["detail"].startswith(f"{field}:"), response.json()


def test_any_unicode_name_imports_and_exports_in_every_format(client, annotator, exported):
    name = 'fall 🚑 01 "quoted" ünï'
    created = _import(client, annotator, "json", json.dumps(changed(exported, "video.name", name)))
    assert created.status_code == 201, created.text
    video = next(
        v
        for v in client.get(f"{API}/videos", headers=annotator.headers).json()
        if v["name"] == name
    )
    for fmt, ext in (("csv", "csv"), ("json", "json"), ("coco", "coco.json")):
        response = _export(client, annotator, video["id"], fmt)
        disposition = response.headers["content-disposition"]
        encoded = disposition.split("filename*=UTF-8''", 1)[1]
        assert unquote(encoded) == f"{name}.{ext}"
    assert client.get(f"{API}/facets", headers=annotator.headers).status_code == 200


def test_content_disposition_holds_any_name_on_one_latin1_line():
    header = attachment('robot-a\r\nSet-Cookie: x=1 "😀"\\.json')
    header.encode("latin-1")  # what the server sends; an emoji raised here before
    assert "\r" not in header and "\n" not in header
    assert header.startswith('attachment; filename="robot-a__Set-Cookie: x=1 ____.json"; ')
    assert unquote(header.split("filename*=UTF-8''")[1]) == 'robot-a\r\nSet-Cookie: x=1 "😀"\\.json'

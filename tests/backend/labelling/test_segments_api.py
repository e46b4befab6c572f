from backend.models.users import Role

API = "/api/labelling"


def _create(client, account, video_id, first, last, label="falling"):
    return client.post(
        f"{API}/videos/{video_id}/segments",
        json={"first_frame": first, "last_frame": last, "label_key": label},
        headers=account.headers,
    )


def test_create_update_delete_keep_exact_frames_and_history(client, urfd_videos, annotator):
    video = urfd_videos["fall-01"]
    created = _create(client, annotator, video, 100, 119)
    assert created.status_code == 201, created.text
    segment = created.json()
    assert (segment["first_frame"], segment["last_frame"]) == (100, 119)
    assert segment["status"] == "draft" and segment["annotator"] == "anna"
    assert segment["decision"] == "emergency"
    moved = client.patch(
        f"{API}/segments/{segment['id']}",
        json={"last_frame": 121, "label_key": "impact"},
        headers=annotator.headers,
    )
    assert moved.status_code == 200 and moved.json()["last_frame"] == 121
    assert (
        client.delete(f"{API}/segments/{segment['id']}", headers=annotator.headers).status_code
        == 204
    )
    listed = client.get(f"{API}/videos/{video}/segments", headers=annotator.headers).json()
    assert segment["id"] not in [s["id"] for s in listed]
    history = client.get(f"{API}/segments/{segment['id']}/history", headers=annotator.headers)
    events = history.json()
    assert [e["action"] for e in events] == ["created", "updated", "deleted"]
    assert events[1]["snapshot"]["label_key"] == "impact" and events[1]["actor"] == "anna"


def test_bad_frames_and_labels_are_rejected_with_the_field_named(client, urfd_videos, annotator):
    video = urfd_videos["fall-01"]  # 160 frames: 0..159
    past_end = _create(client, annotator, video, 150, 160)
    assert past_end.status_code == 422 and "last_frame" in past_end.json()["detail"]
    backwards = _create(client, annotator, video, 50, 40)
    assert backwards.status_code == 422 and "before first_frame" in backwards.json()["detail"]
    assert _create(client, annotator, video, -1, 3).status_code == 422
    unknown = _create(client, annotator, video, 1, 3, label="dancing")
    assert unknown.status_code == 422 and "label_key" in unknown.json()["detail"]
    assert _create(client, annotator, 999_999, 1, 3).status_code == 404
    assert _create(client, annotator, video, 159, 159).status_code == 201


def test_submit_then_another_annotator_reviews(
    client, urfd_videos, annotator, annotator2, make_account
):
    video = urfd_videos["fall-01"]
    ids = [
        _create(client, annotator, video, a, b, k).json()["id"]
        for a, b, k in ((95, 104, "falling"), (105, 159, "lying_on_floor"))
    ]
    submitted = client.post(f"{API}/videos/{video}/submit", headers=annotator.headers)
    assert sorted(submitted.json()["submitted"]) == sorted(ids)
    editing_submitted = client.patch(
        f"{API}/segments/{ids[0]}", json={"first_frame": 90}, headers=annotator.headers
    )
    assert editing_submitted.status_code == 422
    own = client.post(
        f"{API}/segments/{ids[0]}/review", json={"decision": "accept"}, headers=annotator.headers
    )
    assert own.status_code == 403
    no_comment = client.post(
        f"{API}/segments/{ids[1]}/review", json={"decision": "reject"}, headers=annotator2.headers
    )
    assert no_comment.status_code == 422 and "comment" in no_comment.json()["detail"]
    accepted = client.post(
        f"{API}/segments/{ids[0]}/review",
        json={"decision": "accept", "comment": "ok"},
        headers=annotator2.headers,
    )
    assert accepted.json()["status"] == "accepted" and accepted.json()["reviewer"] == "bert"
    again = client.post(
        f"{API}/segments/{ids[0]}/review",
        json={"decision": "reject", "comment": "x"},
        headers=annotator2.headers,
    )
    assert again.status_code == 409
    nurse = make_account(Role.NURSE, "ward-a", "nina")
    forbidden = _create(client, nurse, video, 1, 2)
    assert forbidden.status_code == 403


def test_video_list_shows_progress_and_filters(client, urfd_videos, annotator, admin):
    videos = client.get(f"{API}/videos", headers=annotator.headers).json()
    fall = next(v for v in videos if v["name"] == "fall-01")
    assert fall["labelled_frames"] == 160 and fall["status"] == "done" and fall["has_rgb"]
    _create(client, annotator, urfd_videos["adl-01"], 10, 20, "bending")
    client.post(f"{API}/videos/{urfd_videos['adl-01']}/submit", headers=annotator.headers)
    waiting = client.get(f"{API}/videos?unreviewed=true", headers=annotator.headers).json()
    assert [v["name"] for v in waiting] == ["adl-01"] and waiting[0]["status"] == "in_review"
    assert (
        client.patch(
            f"{API}/videos/{urfd_videos['adl-01']}",
            json={"split": "test"},
            headers=annotator.headers,
        ).status_code
        == 403
    )
    changed = client.patch(
        f"{API}/videos/{urfd_videos['adl-01']}",
        json={"split": "test", "person": "P-07"},
        headers=admin.headers,
    )
    assert changed.json()["split"] == "test" and changed.json()["person"] == "P-07"
    tests_only = client.get(f"{API}/videos?split=test&person=P-07", headers=annotator.headers)
    assert [v["name"] for v in tests_only.json()] == ["adl-01"]
    assert "P-07" in client.get(f"{API}/facets", headers=annotator.headers).json()["persons"]


def test_the_taxonomy_endpoint_serves_the_database_copy_in_the_one_shape(client, annotator):
    from vigil.taxonomy import DEFAULT_TAXONOMY

    served = client.get("/api/taxonomy", headers=annotator.headers)
    assert served.status_code == 200
    body = served.json()
    assert body["version"] == DEFAULT_TAXONOMY.version
    assert [(x["key"], x["walking"], x["wheelchair"]) for x in body["labels"]] == [
        (label.key, label.walking, label.wheelchair) for label in DEFAULT_TAXONOMY.labels
    ]
    missing = client.get("/api/taxonomy", params={"version": 99}, headers=annotator.headers)
    assert missing.status_code == 404

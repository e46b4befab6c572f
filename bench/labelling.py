"""`python -m bench.labelling`: labelling workspace timings on the real URFD data, in process
(FastAPI TestClient, SQLite in a temporary directory). Writes bench/results/labelling.json.

- import_urfd_s: all 70 URFD sequences with their official labels;
- rgb_frame_ms: one RGB frame of fall-01 (decode + head blur + JPEG), first request of a clip
  (cold: decodes from the start of the clip) and repeated (warm: the finished JPEG is cached);
  next_frame: the following frame while playing forward (decoded by the read-ahead, blurred
  and encoded on request), median over frames;
- timeline_load_ms: what the label page fetches for fall-01 (video, all frames, segments,
  model lane without a model);
- export_ms per format for fall-01; segment create + update + delete round trip.
"""

from __future__ import annotations

import json
import platform
import statistics
import tempfile
import time
from pathlib import Path

from fastapi.testclient import TestClient

from backend.db import make_engine, make_session_factory, transaction
from backend.labelling.importers.urfd import import_urfd
from backend.main import create_app
from backend.migrate import upgrade
from backend.models.users import Role, User
from backend.security import create_access_token, hash_password
from backend.settings import Settings

RESULTS = Path(__file__).resolve().parent / "results" / "labelling.json"
API = "/api/labelling"


def _ms(start: float) -> float:
    return round((time.perf_counter() - start) * 1000, 2)


def main() -> int:
    with tempfile.TemporaryDirectory() as tmp:
        url = f"sqlite:///{tmp}/bench.db"
        upgrade(url)
        engine = make_engine(url)
        factory = make_session_factory(engine)
        start = time.perf_counter()
        with transaction(factory) as session:
            report = import_urfd(session)
        import_s = round(time.perf_counter() - start, 2)
        with transaction(factory) as session:
            user = User(
                username="bench", password_hash=hash_password("x" * 12), role=Role.ANNOTATOR
            )
            session.add(user)
            session.flush()
            token = create_access_token("bench-secret", user.id, 60)
        engine.dispose()
        settings = Settings(
            database_url=url,
            secret_key="bench-secret",
            labelling_model_dir=None,
            frontend_dir=Path(tmp) / "none",
        )
        headers = {"Authorization": f"Bearer {token}"}
        with TestClient(create_app(settings)) as client:
            videos = {v["name"]: v for v in client.get(f"{API}/videos", headers=headers).json()}
            fall = videos["fall-01"]["id"]

            cold, warm, following = [], [], []
            for frame in (10, 60, 110, 150):
                tools = client.app.state.services.labelling
                tools.rgb_frames.close()  # readers closed: decode from the start
                tools.rgb_frames._frames.clear()
                tools.rgb_jpegs._items.clear()
                start = time.perf_counter()
                assert client.get(f"{API}/videos/{fall}/rgb/{frame}", headers=headers).is_success
                cold.append(_ms(start))
                start = time.perf_counter()
                client.get(f"{API}/videos/{fall}/rgb/{frame}", headers=headers)
                warm.append(_ms(start))
                start = time.perf_counter()
                client.get(f"{API}/videos/{fall}/rgb/{frame + 1}", headers=headers)
                following.append(_ms(start))

            start = time.perf_counter()
            client.get(f"{API}/videos/{fall}", headers=headers)
            client.get(f"/api/videos/{fall}/frames?start=0&end=159", headers=headers)
            client.get(f"{API}/videos/{fall}/segments", headers=headers)
            client.get(f"{API}/videos/{fall}/probability", headers=headers)
            timeline_ms = _ms(start)

            export_ms = {}
            for fmt in ("csv", "json", "coco"):
                start = time.perf_counter()
                assert client.get(
                    f"{API}/videos/{fall}/export?format={fmt}", headers=headers
                ).is_success
                export_ms[fmt] = _ms(start)

            start = time.perf_counter()
            body = {"first_frame": 90, "last_frame": 100, "label_key": "falling"}
            created = client.post(f"{API}/videos/{fall}/segments", headers=headers, json=body)
            segment = created.json()["id"]
            client.patch(f"{API}/segments/{segment}", headers=headers, json={"last_frame": 104})
            client.delete(f"{API}/segments/{segment}", headers=headers)
            edit_ms = _ms(start)

    result = {
        "benchmark": "labelling",
        "data": "URFD (real), 70 sequences; RGB clip fall-01",
        "machine": {"cpus": 2, "python": platform.python_version()},
        "import_urfd_s": import_s,
        "videos": len(report.created),
        "segments_imported": report.segments,
        "rgb_frame_ms": {
            "cold_median": statistics.median(cold),
            "warm_median": statistics.median(warm),
            "next_frame_median": statistics.median(following),
            "cold": cold,
            "warm": warm,
            "next_frame": following,
        },
        "timeline_load_ms": timeline_ms,
        "export_ms": export_ms,
        "segment_create_update_delete_ms": edit_ms,
    }
    RESULTS.parent.mkdir(exist_ok=True)
    RESULTS.write_text(json.dumps(result, indent=2) + "\n")
    print(json.dumps(result, indent=2))
    return 0


if __name__ == "__main__":
    raise SystemExit(main())

"""The frontend's typed client is generated from frontend/openapi.json: it must match the API."""

import json
from pathlib import Path

from backend.main import create_app
from backend.settings import Settings

OPENAPI_JSON = Path(__file__).resolve().parents[1] / "frontend" / "openapi.json"


def test_committed_openapi_matches_the_backend(tmp_path):
    app = create_app(Settings(frontend_dir=tmp_path, database_url="sqlite://"))
    committed = json.loads(OPENAPI_JSON.read_text())
    assert committed == json.loads(json.dumps(app.openapi())), (
        "frontend/openapi.json is stale: run `python -m backend.openapi > frontend/openapi.json`"
        " and `npm run gen:api` in frontend/"
    )

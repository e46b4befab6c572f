"""A rollout change tells the fleet pages at once (issue 35): the engineers' browser sockets
get the fleet's news once the change is committed, never for a change that was refused."""

from __future__ import annotations

from backend.models import Role
from tests.backend.test_fleet_push import FLEET_NEWS, told
from tests.registry_fixtures import derive_model, second_version


def test_a_rollout_change_is_news_once_committed_and_a_refused_one_is_not(
    client, make_account, fleet, urfd_db, register, trained_model_dir, tmp_path
):
    engineer = make_account(Role.ENGINEER, ward=None)
    nurse = make_account(Role.NURSE, ward="ward-a")
    blind = register(
        derive_model(trained_model_dir, tmp_path / "blind", "blind-1", delay_ms=10_000)
    )
    v1 = register(trained_model_dir)
    v2 = register(second_version(trained_model_dir, tmp_path / "v2", 0.55))
    with (
        client.websocket_connect("/ws/browser", headers=engineer.headers) as engineer_ws,
        client.websocket_connect("/ws/browser", headers=nurse.headers) as nurse_ws,
    ):
        assert engineer_ws.receive_json()["type"] == "snapshot"
        assert nurse_ws.receive_json()["type"] == "snapshot"

        # Refused by the gate: rolled back, no news. (The effects of a request run before its
        # response: what a socket was told is known once the call returns.)
        refused = client.post(
            f"/api/models/{blind}/promote",
            headers=engineer.headers,
            json={"scope": "robot", "target": "robot-a"},
        )
        assert refused.status_code == 409, refused.text
        assert told(engineer_ws) == []

        def promoted(model_id: int) -> dict:
            response = client.post(
                f"/api/models/{model_id}/promote",
                headers=engineer.headers,
                json={"scope": "robot", "target": "robot-a"},
            )
            assert response.status_code == 201, response.text
            return response.json()

        promoted(v1)
        assert told(engineer_ws) == FLEET_NEWS
        second = promoted(v2)
        assert told(engineer_ws) == FLEET_NEWS
        rolled = client.post(
            f"/api/deployments/{second['id']}/rollback",
            headers=engineer.headers,
            json={"reason": "misses falls"},
        )
        assert rolled.status_code == 200, rolled.text
        assert told(engineer_ws) == FLEET_NEWS

        # The nurse has no fleet page: none of it reached her.
        assert told(nurse_ws) == []

"""The model version machine (`backend.registry.rollout.MODEL`) declares exactly the moves the
rollout services make: every declared move is made by one of the scenarios below (promotion,
canary, advance, rollback, a second approver), every move they make is declared, and every
other move is refused."""

from __future__ import annotations

import itertools

import pytest

from backend.db import transaction
from backend.models.registry import Deployment, DeploymentScope, ModelStatus, ModelVersion
from backend.models.robots import Robot
from backend.models.users import Role, User
from backend.registry import rollout
from backend.registry.rollout import MODEL, RolloutStateError
from vigil.states import IllegalTransition

C, A, P, R = ModelStatus
GATE = {"passed": True, "checks": []}


def _declared() -> set[tuple[ModelStatus, ModelStatus]]:
    return {(a, b) for a, targets in MODEL.edges.items() for b in targets}


def test_the_model_machine_declares_nine_moves_and_refuses_the_others():
    assert MODEL.edges == {C: {A, P, R}, A: {P, R}, P: {P, R}, R: {A, P}}
    for current, new in itertools.product(ModelStatus, repeat=2):
        model = ModelVersion(version="m-1", status=current)
        if (current, new) in _declared():
            assert MODEL.move(model, new) == new and model.status == new
            continue
        with pytest.raises(RolloutStateError) as refused:
            MODEL.move(model, new)
        assert isinstance(refused.value, IllegalTransition)
        assert str(refused.value) == f"model m-1 cannot go from {current} to {new}"
        assert model.status == current
    assert all(C not in targets for targets in MODEL.edges.values())  # never a candidate again


@pytest.fixture
def moves(monkeypatch) -> list[tuple[ModelStatus, ModelStatus]]:
    """Every (from, to) the rollout services ask of MODEL."""
    made: list[tuple[ModelStatus, ModelStatus]] = []
    move = MODEL.move

    def recording(model, new):
        before = MODEL.state_of(model)
        after = move(model, new)
        made.append((before, after))
        return after

    monkeypatch.setattr(MODEL, "move", recording)
    return made


def test_the_rollout_services_make_exactly_the_declared_moves(session_factory, fleet, moves):
    with transaction(session_factory) as session:
        engineer = User(username="eng", password_hash="x", role=Role.ENGINEER)
        session.add(engineer)
        models = {}
        for version in ("m1", "m2", "m3", "m4"):
            model = ModelVersion(
                version=version,
                mode="walking",
                kind="rf",
                file_path="-",
                sha256="0" * 64,
                manifest={"inputs": ["keypoints"]},
            )
            MODEL.start(model)
            session.add(model)
            models[version] = model
        session.flush()
        m1, m2, m3, m4 = models.values()

        def promote(model, scope, target=None, **options) -> Deployment:
            return rollout.promote(session, model, engineer, scope, target, GATE, **options)[0]

        def status() -> dict[str, ModelStatus]:
            return {v: MODEL.state_of(m) for v, m in models.items()}

        seen: set[tuple[ModelStatus, ModelStatus]] = set()

        def made(*expected) -> None:
            assert moves == list(expected)
            seen.update(moves)
            moves.clear()

        # A canary in ward-a approves a candidate; the advance puts it in production.
        ward_a = promote(m1, DeploymentScope.WARD, "ward-a", canary_robot_id="robot-a")
        made((C, A))
        session.get(Robot, "robot-a").running_model_version = "m1"
        rollout.advance(session, ward_a)
        made((A, P))
        # One robot: straight to production.
        promote(m2, DeploymentScope.ROBOT, "robot-d")
        made((C, P))
        # A canary of a model in production elsewhere leaves it in production (the fallback
        # of its mode); rolled back, robot-d gets m2 back (production -> production) and m1,
        # still on ward-a, stays in production.
        canary = promote(m1, DeploymentScope.FLEET, canary_robot_id="robot-d")
        made()
        assert status()["m1"] == P
        rollout.rollback(session, canary, "test")
        made((P, P))
        assert status()["m1"] == P
        # A pending deployment rolled back retires its candidate.
        pending = promote(m3, DeploymentScope.ROBOT, "robot-b", require_second_approver=True)
        made()
        rollout.rollback(session, pending, "test")
        made((C, R))
        # A retired model promoted again: canary (approved) and rolled back (retired again).
        canary = promote(m3, DeploymentScope.WARD, "ward-a", canary_robot_id="robot-a")
        made((R, A))
        rollout.rollback(session, canary, "test")
        made((P, P), (A, R))
        # ... and to one robot (production), rolled back (retired).
        single = promote(m3, DeploymentScope.ROBOT, "robot-b")
        made((R, P))
        rollout.rollback(session, single, "test")
        made((P, P), (P, R))
        # A retired model's pending deployment rolled back: it stays retired.
        pending = promote(m3, DeploymentScope.ROBOT, "robot-b", require_second_approver=True)
        rollout.rollback(session, pending, "test")
        made()
        assert status()["m3"] == R
        # A rollback gives a robot back a model retired meanwhile: in production again.
        on_c = promote(m2, DeploymentScope.ROBOT, "robot-c")  # m2 on robot-c and robot-d
        made((P, P))
        on_d = promote(m4, DeploymentScope.ROBOT, "robot-d")  # robot-d leaves m2
        made((C, P))
        rollout.rollback(session, on_c, "test")  # robot-c back to m1: no robot left on m2
        made((P, P), (P, R))
        rollout.rollback(session, on_d, "test")  # robot-d back to m2
        made((R, P), (P, R))
        assert status() == {"m1": P, "m2": P, "m3": R, "m4": R}
        session.rollback()
    assert seen == _declared()  # every declared move is one the services make

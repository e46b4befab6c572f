"""The one transition-table helper: edges or named actions, one way to change a state, and an
IllegalTransition with a readable message for anything the table does not allow."""

from enum import StrEnum
from types import SimpleNamespace

import pytest

from vigil.states import IllegalTransition, StateMachine


class Door(StrEnum):
    OPEN = "open"
    CLOSED = "closed"
    LOCKED = "locked"


BY_EDGES = StateMachine(
    Door,
    edges={Door.OPEN: {Door.CLOSED}, Door.CLOSED: {Door.OPEN, Door.LOCKED}},
    attribute="state",
    initial=Door.CLOSED,
    subject=lambda door: f"door {door.name}",
)


class DoorError(IllegalTransition):
    pass


BY_ACTIONS = StateMachine(
    Door,
    actions={
        "open": {Door.CLOSED: Door.OPEN},
        "close": {Door.OPEN: Door.CLOSED, Door.CLOSED: Door.CLOSED},
        "lock": {Door.CLOSED: Door.LOCKED},
    },
    subject="door",
    error=DoorError,
)


def test_move_changes_the_attribute_only_along_an_edge():
    door = SimpleNamespace(name="front")
    assert BY_EDGES.start(door) is Door.CLOSED and door.state is Door.CLOSED
    assert BY_EDGES.move(door, "open") is Door.OPEN and door.state is Door.OPEN
    with pytest.raises(IllegalTransition, match="door front cannot go from open to locked"):
        BY_EDGES.move(door, Door.LOCKED)
    assert door.state is Door.OPEN  # unchanged by a refused move
    assert not BY_EDGES.allows(Door.OPEN, Door.OPEN)  # a self-loop must be declared
    assert BY_EDGES.edges[Door.LOCKED] == frozenset()  # an undeclared state goes nowhere


def test_act_follows_named_actions_and_raises_the_machines_error():
    door = SimpleNamespace(status="closed")  # a plain string from the database works too
    assert BY_ACTIONS.act(door, "close") is Door.CLOSED
    assert BY_ACTIONS.act(door, "open") is Door.OPEN
    with pytest.raises(DoorError, match="cannot lock a door that is open") as refused:
        BY_ACTIONS.act(door, "lock")
    assert (refused.value.state, refused.value.action) == (Door.OPEN, "lock")
    with pytest.raises(DoorError, match="unknown action 'kick' \\(one of open, close, lock\\)"):
        BY_ACTIONS.act(door, "kick")
    assert BY_ACTIONS.edges[Door.CLOSED] == {Door.OPEN, Door.CLOSED, Door.LOCKED}
    assert isinstance(DoorError("door", Door.OPEN, target=Door.LOCKED), ValueError)


def test_column_checks_before_an_sql_update_and_declarations_are_checked():
    assert BY_EDGES.column(Door.CLOSED, Door.LOCKED) == {"state": Door.LOCKED}
    with pytest.raises(IllegalTransition, match="cannot go from locked to open"):
        BY_EDGES.column("locked", "open")
    with pytest.raises(ValueError, match="one of them"):
        StateMachine(Door, edges={}, actions={})
    with pytest.raises(ValueError, match="no initial state"):
        BY_ACTIONS.start(SimpleNamespace(status=None))


def test_declared_entries_start_an_object_in_their_state_and_only_those():
    machine = StateMachine(
        Door,
        edges={Door.OPEN: {Door.CLOSED}, Door.CLOSED: {Door.OPEN}},
        attribute="state",
        initial=Door.CLOSED,
        entries={"installed_open": Door.OPEN},
    )
    door = SimpleNamespace(state=None)
    assert machine.start(door) == Door.CLOSED and door.state == Door.CLOSED
    assert machine.start(door, "installed_open") == Door.OPEN and door.state == Door.OPEN
    with pytest.raises(ValueError, match="no entry 'broken'.*installed_open"):
        machine.start(door, "broken")
    assert door.state == Door.OPEN  # unchanged by the refused start

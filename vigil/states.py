"""State machines, each declared once beside its enum with this one helper.

A machine lists the transitions it allows, either as edges (state -> the states it may go to)
or as named actions (action -> {from state: to state}). Its `move` (by target state) and `act`
(by action) are the only code that changes an object's state attribute; `check` / `target`
only ask, and `column` gives the checked value for an SQL `UPDATE ... SET`.
`tests/test_state_machines.py` fails on any other assignment to a state attribute.

An illegal transition raises `IllegalTransition` (or the machine's subclass of it) with a
message a person can read; the backend answers it with HTTP 409 and that message, in one
exception handler (`backend.main`).

Machines: alarm (`backend.alarms.state`), label segment (`backend.labelling.status`), job
(`backend.jobs.queue`), model version and rollout (`backend.registry.rollout`), retention run
(`backend.storage.retention`), patient tracker (`vigil.tracking`), the robot's local alarm
(`robot_agent.alarm`), the robot's behaviour (`robot_agent.behaviour`).
"""

from __future__ import annotations

from collections.abc import Callable, Iterable, Mapping
from enum import Enum
from typing import Any, Generic, TypeVar

S = TypeVar("S", bound=Enum)


def _article(noun: str) -> str:
    return f"{'an' if noun[:1].lower() in 'aeiou' else 'a'} {noun}"


class IllegalTransition(ValueError):
    """A transition the machine does not allow (HTTP 409 in the backend)."""

    def __init__(
        self,
        subject: str,
        state: Any,
        *,
        target: Any = None,
        action: str | None = None,
        unknown_action: bool = False,
        actions: Iterable[str] = (),
    ) -> None:
        self.subject = subject
        self.state = state
        self.target = target
        self.action = action
        self.unknown_action = unknown_action
        self.actions = tuple(actions)
        super().__init__(self.message())

    def message(self) -> str:
        if self.unknown_action:
            return f"unknown action {self.action!r} (one of {', '.join(self.actions)})"
        if self.action is not None:
            return f"cannot {self.action} {_article(self.subject)} that is {_value(self.state)}"
        return f"{self.subject} cannot go from {_value(self.state)} to {_value(self.target)}"


def _value(state: Any) -> Any:
    return state.value if isinstance(state, Enum) else state


class StateMachine(Generic[S]):
    """The allowed transitions of one enum, and the one way to change an object's state.

    `edges`: state -> the states it may go to (a self-loop must be listed to be allowed).
    `actions`: action name -> {from state: to state}; the edges are then derived from them.
    `attribute`: the object's attribute that holds the state.
    `initial`: the state `start` puts an object in (a new or reset object).
    `entries`: the other ways an object may come into being, by name, each with the state it
    starts in (e.g. a dataset's labels are imported "accepted"): declared here, once, so no
    object is created straight into a state the machine does not know as a start.
    `subject`: names the object in messages ("job", or a function of the object).
    `error`: the IllegalTransition subclass to raise.
    """

    def __init__(
        self,
        states: type[S],
        *,
        edges: Mapping[S, Iterable[S]] | None = None,
        actions: Mapping[str, Mapping[S, S]] | None = None,
        attribute: str = "status",
        initial: S | None = None,
        entries: Mapping[str, S] | None = None,
        subject: str | Callable[[Any], str] | None = None,
        error: type[IllegalTransition] = IllegalTransition,
    ) -> None:
        if (edges is None) == (actions is None):
            raise ValueError("declare a state machine by edges or by actions (one of them)")
        self.states = states
        self.actions: dict[str, dict[S, S]] = {
            name: {states(a): states(b) for a, b in moves.items()}
            for name, moves in (actions or {}).items()
        }
        if edges is None:
            derived: dict[S, set[S]] = {}
            for moves in self.actions.values():
                for a, b in moves.items():
                    derived.setdefault(a, set()).add(b)
            edges = derived
        self.edges: dict[S, frozenset[S]] = {
            state: frozenset(states(t) for t in edges.get(state, ())) for state in states
        }
        unknown = set(edges) - set(states)
        if unknown:
            raise ValueError(f"states not in {states.__name__}: {sorted(map(str, unknown))}")
        self.attribute = attribute
        self.initial = initial
        self.entries: dict[str, S] = {name: states(s) for name, s in (entries or {}).items()}
        self.subject = subject or states.__name__
        self.error = error

    # -- asking -------------------------------------------------------------------------------

    def _state(self, value: S | str) -> S:
        # An enum call costs microseconds; the tracker moves on every frame.
        return value if type(value) is self.states else self.states(value)

    def allows(self, current: S | str, new: S | str) -> bool:
        return self._state(new) in self.edges[self._state(current)]

    def check(self, current: S | str, new: S | str, obj: Any = None) -> S:
        """The new state, if `current -> new` is allowed; raises otherwise."""
        current, new = self._state(current), self._state(new)
        if new not in self.edges[current]:
            raise self.error(self._subject(obj), current, target=new)
        return new

    def target(self, current: S | str, action: str, obj: Any = None) -> S:
        """Where `action` takes an object in state `current`; raises if it may not."""
        if action not in self.actions:
            raise self.error(
                self._subject(obj),
                current,
                action=action,
                unknown_action=True,
                actions=self.actions,
            )
        current = self._state(current)
        try:
            return self.actions[action][current]
        except KeyError:
            raise self.error(self._subject(obj), current, action=action) from None

    def column(self, current: S | str, new: S | str, obj: Any = None) -> dict[str, S]:
        """`{attribute: new}` for an SQL `UPDATE ... SET`, after checking `current -> new`."""
        return {self.attribute: self.check(current, new, obj)}

    def state_of(self, obj: Any) -> S:
        return self._state(getattr(obj, self.attribute))

    # -- changing: the only writes of a state attribute ----------------------------------------

    def move(self, obj: Any, new: S | str) -> S:
        """Put `obj` in state `new` if its current state allows it; returns the new state."""
        new = self.check(getattr(obj, self.attribute), new, obj)
        setattr(obj, self.attribute, new)
        return new

    def act(self, obj: Any, action: str) -> S:
        """Apply the named action to `obj`; returns the new state."""
        new = self.target(getattr(obj, self.attribute), action, obj)
        setattr(obj, self.attribute, new)
        return new

    def start(self, obj: Any, entry: str | None = None) -> S:
        """Put a new (or reset) object in the machine's initial state, or in the state of one
        of its declared `entries` (by name)."""
        if entry is not None:
            if entry not in self.entries:
                raise ValueError(
                    f"{self.states.__name__}: no entry {entry!r} (declared: {sorted(self.entries)})"
                )
            state = self.entries[entry]
        elif self.initial is None:
            raise ValueError(f"{self.states.__name__}: no initial state declared")
        else:
            state = self.initial
        setattr(obj, self.attribute, state)
        return state

    def _subject(self, obj: Any) -> str:
        if callable(self.subject):
            return self.subject(obj) if obj is not None else self.states.__name__
        return self.subject

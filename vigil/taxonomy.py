"""Fine labels (stages of a fall, everyday situations) and their class per transport mode.

The taxonomy is versioned data: the database holds the editable copy (seeded from
DEFAULT_TAXONOMY by a migration); models record the version they were trained on. `Taxonomy` is
its one shape: the backend loads the database's copy as one (backend.labelling.taxonomy), the
API serialises it, the worker reads the classes of training labels from it.
"""

from __future__ import annotations

from dataclasses import dataclass

from vigil.classes import Decision, TransportMode

N, E, P = Decision.NORMAL, Decision.EMERGENCY, Decision.PAUSE


@dataclass(frozen=True, slots=True)
class FineLabel:
    key: str
    name: str
    walking: Decision
    wheelchair: Decision
    combined: Decision

    def decision(self, mode: TransportMode) -> Decision:
        return getattr(self, TransportMode(mode).value)


@dataclass(frozen=True, slots=True)
class Taxonomy:
    version: int
    labels: tuple[FineLabel, ...]

    def __post_init__(self) -> None:
        keys = [label.key for label in self.labels]
        if len(set(keys)) != len(keys):
            raise ValueError("fine label keys must be unique")
        for label in self.labels:
            if label.walking == Decision.PAUSE:
                raise ValueError(f"{label.key}: walking mode has only Normal and Emergency")

    def by_key(self, key: str) -> FineLabel:
        label = self.get(key)
        if label is None:
            raise KeyError(f"unknown fine label {key!r}")
        return label

    def get(self, key: str) -> FineLabel | None:
        """The fine label called `key`, or None (a placeholder or a label of another version)."""
        for label in self.labels:
            if label.key == key:
                return label
        return None

    def __contains__(self, key: object) -> bool:
        return any(label.key == key for label in self.labels)

    def decision(self, key: str, mode: TransportMode) -> Decision:
        return self.by_key(key).decision(mode)


def _label(key: str, name: str, cls: Decision, walking: Decision | None = None) -> FineLabel:
    # Walking transports are binary (the paper's walking set has no Pause frames): a Pause
    # situation there is Normal; wheelchair and combined modes keep all three classes.
    walk = walking if walking is not None else (N if cls == P else cls)
    return FineLabel(key, name, walk, cls, cls)


DEFAULT_TAXONOMY = Taxonomy(
    version=1,
    labels=(
        _label("walking", "Walking", N),
        _label("walking_rollator", "Walking with rollator", N),
        _label("standing", "Standing", N),
        _label("turning", "Turning", N),
        _label("sitting_wheelchair", "Sitting in wheelchair", N),
        _label("sitting_down", "Sitting down", N),
        _label("kneeling", "Kneeling (tying a shoe)", N),
        _label("bending", "Bending (picking something up)", N),
        _label("gesturing", "Gesturing", N),
        _label("lying_down_deliberately", "Lying down deliberately", N),
        _label("stumbling", "Stumbling", E),
        _label("stumbling_rollator", "Stumbling with rollator", E),
        _label("falling", "Falling", E),
        _label("impact", "Impact", E),
        _label("lying_on_floor", "Lying on the floor", E),
        _label("sitting_on_floor_after_fall", "Sitting on the floor after a fall", E),
        _label("trying_to_get_up", "Trying to get up after a fall", E),
        _label("slumped_unconscious_wheelchair", "Slumped unconscious in wheelchair", E),
        _label("falling_out_of_wheelchair", "Falling out of wheelchair", E),
        _label("too_far_away", "Too far away", P),
        _label("standing_up_from_wheelchair", "Standing up from wheelchair", P),
        _label("crushing_hazard", "Crushing hazard (arms or legs outside wheelchair)", P),
    ),
)

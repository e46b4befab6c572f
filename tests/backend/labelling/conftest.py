from __future__ import annotations

import pytest

from backend.db import transaction
from backend.labelling.importers.urfd import import_urfd
from backend.models.users import Role
from backend.models.videos import Video
from vigil.datasets import urfd

URFD_DIR = urfd.default_dir()


@pytest.fixture
def settings(settings):
    """No model lane unless a test asks for one (the repo's var/ may hold a trained model)."""
    return settings.model_copy(update={"labelling_model_dir": None})


@pytest.fixture(scope="session")
def urfd_sequences() -> list[urfd.Sequence]:
    return urfd.load(URFD_DIR, ["fall-01", "adl-01"])


@pytest.fixture
def urfd_videos(session_factory, urfd_sequences) -> dict[str, int]:
    """fall-01 (with RGB clip and depth) and adl-01, imported from the real URFD files."""
    with transaction(session_factory) as session:
        import_urfd(session, URFD_DIR, sequences=urfd_sequences)
    with session_factory() as session:
        return {v.name: v.id for v in session.query(Video)}


@pytest.fixture
def annotator(make_account):
    return make_account(Role.ANNOTATOR, None, "anna")


@pytest.fixture
def annotator2(make_account):
    return make_account(Role.ANNOTATOR, None, "bert")


@pytest.fixture
def engineer(make_account):
    return make_account(Role.ENGINEER, None, "erin")


@pytest.fixture
def admin(make_account):
    return make_account(Role.ADMIN, None, "ada")

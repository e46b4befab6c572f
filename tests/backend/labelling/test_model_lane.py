"""The model lane computed with vigil.runtime from a small model trained here on real URFD
sequences (not fall-01, the video it is then run on)."""

import numpy as np
import pytest
from fastapi.testclient import TestClient

from backend.main import create_app
from tests.backend.labelling.conftest import URFD_DIR
from tests.support.model_cache import trained_once
from vigil.datasets import urfd


@pytest.fixture(scope="session")
def tiny_model(tmp_path_factory):
    from worker.training.cross_validation import select
    from worker.training.data import from_urfd
    from worker.training.estimators import ModelSpec
    from worker.training.publish import publish
    from worker.training.trainers import SklearnTrainer

    def train(out) -> None:
        names = [f"fall-{i:02d}" for i in range(2, 7)] + [f"adl-{i:02d}" for i in range(1, 5)]
        data = from_urfd(URFD_DIR, names)
        spec = ModelSpec(
            name="rf-tiny",
            family="rf",
            grid={
                "n_estimators": [10],
                "max_depth": [6],
                "min_samples_leaf": [5],
                "max_features": [0.3],
            },
            description="small test model",
        )
        trainer = SklearnTrainer(spec)
        selected = select(trainer, data, np.arange(len(names)), n_inner=2, stride=2)
        publish(trainer, selected, data, out, version="rf-tiny-test")

    return trained_once("rf-tiny", train, tmp_path_factory.mktemp("model"))


def test_lane_is_computed_when_no_scores_are_stored(settings, tiny_model, urfd_videos, annotator):
    app = create_app(settings.model_copy(update={"labelling_model_dir": tiny_model}))
    with TestClient(app) as client:
        response = client.get(
            f"/api/labelling/videos/{urfd_videos['fall-01']}/probability", headers=annotator.headers
        )
    lane = response.json()
    assert lane["source"] == "model" and lane["model_version"] == "rf-tiny-test"
    p = np.array(lane["probability"], dtype=float)
    assert p.shape == (160,) and np.all((p >= 0) & (p <= 1))
    label = urfd.load(URFD_DIR, ["fall-01"])[0].urfd_label
    assert p[label == 1].mean() > p[label == -1].mean() + 0.3
    lying = set(np.flatnonzero(label == 1).tolist())
    suggested = {
        i for s in lane["suggestions"] for i in range(s["first_frame"], s["last_frame"] + 1)
    }
    assert len(suggested & lying) > 0.5 * len(lying)


def test_a_broken_model_leaves_labelling_usable(
    settings, tiny_model, urfd_videos, annotator, tmp_path
):
    import shutil

    broken = tmp_path / "broken"
    shutil.copytree(tiny_model, broken)
    with (broken / "model.onnx").open("ab") as handle:
        handle.write(b"tampered")
    app = create_app(settings.model_copy(update={"labelling_model_dir": broken}))
    with TestClient(app) as client:
        response = client.get(
            f"/api/labelling/videos/{urfd_videos['fall-01']}/probability", headers=annotator.headers
        )
    assert response.status_code == 200
    lane = response.json()
    assert lane["source"] == "none" and lane["suggestions"] == []
    assert "could not score" in lane["error"]

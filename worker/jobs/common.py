"""Pieces several jobs share: parameters, the gold set, the evaluation stored with a model."""

from __future__ import annotations

import re
import shutil
from pathlib import Path

from sqlalchemy.orm import Session

from backend.models.registry import ModelVersion
from backend.models.users import User
from backend.models.videos import Split
from vigil.classes import TransportMode
from vigil.model_file import Classifier, load_classifier
from worker import evaluation
from worker.context import JobContext
from worker.db_data import frame_data, labelled_videos


def started_by(session: Session, context: JobContext) -> dict:
    user = session.get(User, context.created_by_id) if context.created_by_id else None
    return {
        "user_id": user.id if user else None,
        "username": user.username if user else None,
        "job_id": context.job_id,
    }


def model_or_error(session: Session, model_id: int) -> ModelVersion:
    model = session.get(ModelVersion, model_id)
    if model is None:
        raise ValueError(f"invalid job parameter model_version_id: model {model_id} not found")
    return model


def model_dir(model: ModelVersion) -> Path:
    return Path(model.file_path).parent


def gold_evaluation(
    session: Session,
    classifier: Classifier,
    directory: Path,
    mode: TransportMode,
    sweep: dict | None = None,
) -> dict:
    """Gold-set evaluation (videos with split 'test'), latency and plots written to directory."""
    metrics: dict = {"latency": evaluation.measure_latency(directory)}
    videos = labelled_videos(session, mode, Split.TEST)
    if not videos:
        metrics["gold"] = None
        metrics["gold_note"] = "no gold set: no labelled recordings with split 'test'"
        return metrics
    data = frame_data(session, videos, mode)
    result = evaluation.evaluate_model(classifier, data)
    plots_dir = directory / "plots"
    shutil.rmtree(plots_dir, ignore_errors=True)
    metrics["gold"] = result
    metrics["plots"] = evaluation.write_plots(classifier, data, result, plots_dir, sweep)
    return metrics


def reload(directory: Path) -> Classifier:
    return load_classifier(directory)


#: Longest model version name (ModelVersion.version).
VERSION_LIMIT = 64


def derived_version(parent: str, tag: str, job_id: int, limit: int = VERSION_LIMIT) -> str:
    """The name of a version derived from `parent` by a job: the parent's name without an
    earlier derivation's suffix, then `-<tag><job id>` (unique: one job, one version). A long
    parent is shortened at a hyphen, never inside a word or a timestamp."""
    base = re.sub(r"(-(rt|j)\d+)+$", "", parent)
    suffix = f"-{tag}{job_id}"
    while len(base) + len(suffix) > limit and "-" in base:
        base = base.rsplit("-", 1)[0]
    return base[: limit - len(suffix)] + suffix

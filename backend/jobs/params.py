"""Parameters of each job kind: checked when a job is queued (HTTP 422 naming the field) and
again by the worker. Pydantic only, so the backend can import this without training code."""

from __future__ import annotations

from pathlib import Path
from typing import TypeVar

from pydantic import BaseModel, ConfigDict, Field, ValidationError

from backend.models.jobs import JobKind
from backend.models.videos import Split
from vigil.classes import TransportMode

VERSION_PATTERN = r"^[A-Za-z0-9_.-]+$"


class JobParams(BaseModel):
    model_config = ConfigDict(extra="forbid")


class RetrainParams(JobParams):
    mode: TransportMode = TransportMode.WALKING
    spec: str = Field(default="rf-default", description="model family and grid by name")
    grid: dict[str, list] | None = Field(default=None, description="override the spec's grid")
    video_ids: list[int] | None = Field(default=None, description="default: split 'train'")
    n_inner: int = Field(default=4, ge=2, le=10)
    stride: int = Field(default=2, ge=1, le=30)
    version: str | None = Field(default=None, max_length=64, pattern=VERSION_PATTERN)
    archive_ids: list[int] | None = Field(
        default=None,
        description="archived videos (frame_archives ids) imported again and trained on too",
    )


class RethresholdParams(JobParams):
    model_version_id: int
    video_ids: list[int] | None = Field(default=None, description="default: split 'train'")
    version: str | None = Field(default=None, max_length=64, pattern=VERSION_PATTERN)


class EvaluateParams(JobParams):
    model_version_id: int


class RegisterParams(JobParams):
    path: str = Field(
        min_length=1,
        max_length=4096,
        description="model directory inside the model store (absolute, or relative to it)",
    )


class WhatIfParams(JobParams):
    model_version_id: int
    threshold: float = Field(ge=0.0, le=1.0)
    delay_ms: int = Field(ge=0, le=10_000)
    split: Split = Split.TEST
    video_ids: list[int] | None = None


class RetentionParams(JobParams):
    dry_run: bool = Field(default=False, description="record what would go, drop nothing")


P = TypeVar("P", bound=JobParams)

PARAMS: dict[JobKind, type[JobParams]] = {
    JobKind.RETRAIN: RetrainParams,
    JobKind.RETHRESHOLD: RethresholdParams,
    JobKind.EVALUATE: EvaluateParams,
    JobKind.REGISTER: RegisterParams,
    JobKind.WHATIF: WhatIfParams,
    JobKind.RETENTION: RetentionParams,
}


def parse(model: type[P], params: dict) -> P:
    """Validate; a problem raises ValueError naming the parameter."""
    try:
        return model.model_validate(params)
    except ValidationError as error:
        first = error.errors()[0]
        where = ".".join(str(p) for p in first["loc"]) or "params"
        raise ValueError(f"invalid job parameter {where}: {first['msg']}") from None


def register_source(path: str, model_store_dir: Path | str) -> Path:
    """The model directory a register job may read: inside the model store only (symlinks and
    '..' resolved first), never elsewhere on the worker's host; ValueError naming `path`."""
    store = Path(model_store_dir).resolve()
    try:
        source = (store / path).resolve()  # an absolute path replaces the store
    except (OSError, RuntimeError, ValueError) as error:
        raise ValueError(f"invalid job parameter path: {error}") from None
    if source == store or not source.is_relative_to(store):
        raise ValueError(
            f"invalid job parameter path: {path} is not a model directory inside the model "
            f"store ({store}); registration reads only from the model store"
        )
    return source


def validate(kind: JobKind, params: dict, model_store_dir: Path | str | None = None) -> dict:
    """The parameters as stored: validated, defaults left implicit. With `model_store_dir` (a
    job queued by a user), a register job's path must lie inside the model store."""
    checked = parse(PARAMS[JobKind(kind)], params)
    if isinstance(checked, RegisterParams) and model_store_dir is not None:
        register_source(checked.path, model_store_dir)
    return params

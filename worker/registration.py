"""Put a model directory (ONNX + manifest) into the model store and the registry table."""

from __future__ import annotations

import shutil
import subprocess
from functools import cache
from pathlib import Path

from sqlalchemy.orm import Session

from backend.models.registry import ModelVersion
from backend.registry.queries import model_by_version
from backend.registry.rollout import MODEL
from vigil.model_file import MANIFEST_NAME, load_classifier, read_manifest

REPO_ROOT = Path(__file__).resolve().parent.parent


@cache
def code_version() -> str:
    """The git commit of the code that trained the model (with -dirty), or 'unknown'."""
    try:
        sha = subprocess.run(
            ["git", "rev-parse", "HEAD"],
            cwd=REPO_ROOT,
            capture_output=True,
            text=True,
            check=True,
            timeout=5,
        ).stdout.strip()
        dirty = subprocess.run(
            ["git", "status", "--porcelain", "--untracked-files=no"],
            cwd=REPO_ROOT,
            capture_output=True,
            text=True,
            timeout=5,
        ).stdout.strip()
        return f"{sha}-dirty" if dirty else sha
    except (OSError, subprocess.SubprocessError):
        return "unknown"


def store_path(store_dir: Path, version: str) -> Path:
    if "/" in version or "\\" in version or version in ("", ".", ".."):
        raise ValueError(f"version {version!r} is not a plain name")
    return Path(store_dir) / version


def refuse_registered(session: Session, version: str) -> None:
    if model_by_version(session, version) is not None:
        raise ValueError(f"model version {version} is already registered")


def copy_to_store(model_dir: Path, store_dir: Path) -> Path:
    """The model's directory in the store (model file, manifest, plots copied there unless the
    model is there already)."""
    manifest, source = read_manifest(model_dir)
    target = store_path(store_dir, manifest.version)
    if Path(source).resolve() != target.resolve():
        target.mkdir(parents=True, exist_ok=True)
        shutil.copyfile(source / manifest.file, target / manifest.file)
        shutil.copyfile(source / MANIFEST_NAME, target / MANIFEST_NAME)
        if (source / "plots").is_dir():
            shutil.copytree(source / "plots", target / "plots", dirs_exist_ok=True)
    return target


def register(
    session: Session,
    model_dir: Path,
    store_dir: Path,
    *,
    lineage: dict,
    metrics: dict | None = None,
    job_id: int | None = None,
    created_by_id: int | None = None,
) -> ModelVersion:
    """Verify the model (sha256 of its manifest), copy it to the store and add a candidate. Its
    lineage's `training_videos` are its manifest's training recordings unless `lineage` names
    them."""
    classifier = load_classifier(model_dir)  # raises ModelIntegrityError on a bad file
    manifest = classifier.manifest
    refuse_registered(session, manifest.version)
    target = copy_to_store(model_dir, store_dir)
    model = ModelVersion(
        version=manifest.version,
        mode=manifest.mode,
        kind=manifest.name,
        format=manifest.format,
        file_path=str(target / manifest.file),
        sha256=manifest.sha256,
        manifest=manifest.model_dump(mode="json"),
        metrics=metrics or {},
        lineage={
            "taxonomy_version": manifest.taxonomy_version,
            "feature_version": manifest.feature_version,
            "data_sha256": manifest.training_data_sha256,
            "generated_data": manifest.generated_data,
            "code_version": code_version(),
            # What it was trained on, from its manifest (a job may name more): the promotion
            # gate refuses a gold set that overlaps it, and a model without it.
            "training_videos": manifest.training_recordings,
            **lineage,
        },
        job_id=job_id,
        created_by_id=created_by_id,
    )
    MODEL.start(model)  # a candidate
    session.add(model)
    session.flush()
    return model

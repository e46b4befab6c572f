"""Model updates: on `assign_model` download the ONNX file and its manifest with the robot's
token, check the file's sha256 against the manifest (and the assignment), store it, load it
(which checks the hash once more) and hand it to the pipeline to swap in between two frames.

A file whose hash does not match is refused: nothing is stored, the refusal is logged and
reported to the backend in the next heartbeat (`model_error`), and the old model keeps running.

A model already on the robot is checked against the registry's sha256 too (the file on disk and
its local manifest may both have been changed): at start against the sha256 noted in `RUNNING`
with the assignment, after every `welcome` against the registry's sha256 the backend sends, and
at every assignment of the version it runs (robot_agent.agent).
"""

from __future__ import annotations

import hashlib
import json
import logging
import shutil
import tempfile
import urllib.error
import urllib.request
from dataclasses import dataclass
from pathlib import Path

from vigil.classes import TransportMode
from vigil.model_file import MANIFEST_NAME, ModelIntegrityError, ModelManifest
from vigil.protocol import ModelAssignment
from vigil.runtime import FrameClassifier

log = logging.getLogger(__name__)
DOWNLOAD_TIMEOUT_S = 30


class ModelRefused(Exception):
    """An assigned model that must not run: bad hash, wrong mode, unreadable manifest."""


@dataclass(frozen=True)
class Refusal:
    """A model on the robot that must not run (its file is not the registry's), and why."""

    version: str
    reason: str


def _get(url: str, robot_id: str, token: str) -> bytes:
    request = urllib.request.Request(
        url, headers={"X-Robot-Id": robot_id, "Authorization": f"Bearer {token}"}
    )
    try:
        with urllib.request.urlopen(request, timeout=DOWNLOAD_TIMEOUT_S) as response:
            return response.read()
    except urllib.error.HTTPError as error:
        detail = error.read()[:200].decode(errors="replace")
        raise ModelRefused(f"download of {url} failed: HTTP {error.code} {detail}") from None
    except (urllib.error.URLError, OSError) as error:
        raise ModelRefused(f"download of {url} failed: {error}") from None


def manifest_url(file_url: str) -> str:
    base, _, last = file_url.rstrip("/").rpartition("/")
    if last != "file":
        raise ModelRefused(f"unexpected model URL {file_url}")
    return f"{base}/manifest"


def fetch_model(
    assignment: ModelAssignment,
    robot_id: str,
    token: str,
    models_dir: Path,
    mode: TransportMode,
) -> FrameClassifier:
    """Download, verify, store and load an assigned model (blocking: run it in a thread).
    A copy stored earlier with the assignment's sha256 is loaded without downloading."""
    stored = models_dir / assignment.version
    if (stored / MANIFEST_NAME).is_file():
        try:
            classifier = FrameClassifier.from_dir(stored)  # checks the file's sha256
            manifest = classifier.manifest
            if manifest.sha256 == assignment.sha256 and manifest.mode == TransportMode(mode):
                log.info("model %s found in %s, verified", assignment.version, stored)
                return classifier
        except Exception as error:  # damaged copy: download it again
            log.warning("stored model %s unusable (%s): downloading it", stored, error)
    data = _get(assignment.url, robot_id, token)
    try:
        manifest_json = json.loads(_get(manifest_url(assignment.url), robot_id, token))
        manifest = ModelManifest.model_validate(manifest_json)
    except ValueError as error:
        raise ModelRefused(f"manifest of {assignment.version} is invalid: {error}") from None
    actual = hashlib.sha256(data).hexdigest()
    if actual != manifest.sha256 or actual != assignment.sha256:
        raise ModelRefused(
            f"model {assignment.version} refused: sha256 of the downloaded file is {actual}, "
            f"the manifest says {manifest.sha256}"
        )
    if manifest.version != assignment.version:
        raise ModelRefused(
            f"model {assignment.version} refused: its manifest is for version {manifest.version}"
        )
    if manifest.mode != TransportMode(mode):
        raise ModelRefused(
            f"model {assignment.version} refused: it is for {manifest.mode.value} transports, "
            f"this robot runs {TransportMode(mode).value}"
        )
    models_dir.mkdir(parents=True, exist_ok=True)
    target = models_dir / manifest.version
    staging = Path(tempfile.mkdtemp(prefix=".incoming-", dir=models_dir))
    try:
        (staging / manifest.file).write_bytes(data)
        (staging / MANIFEST_NAME).write_text(json.dumps(manifest_json, indent=2))
        classifier = FrameClassifier.from_dir(staging)  # checks the sha256 again, then loads
        if target.exists():
            shutil.rmtree(target)
        staging.rename(target)
    except Exception as error:
        shutil.rmtree(staging, ignore_errors=True)
        if isinstance(error, ModelRefused):
            raise
        raise ModelRefused(f"model {assignment.version} could not be loaded: {error}") from None
    return classifier


RUNNING_FILE = "RUNNING"


def remember_running(models_dir: Path, version: str, sha256: str | None = None) -> None:
    """Note the assigned model now running and the registry's sha256 of it (from the
    assignment), so that a restart starts with it, and only if its file still matches."""
    models_dir.mkdir(parents=True, exist_ok=True)
    temporary = models_dir / f".{RUNNING_FILE}.tmp"
    temporary.write_text(version + (f" {sha256}" if sha256 else "") + "\n")
    temporary.replace(models_dir / RUNNING_FILE)


def forget_running(models_dir: Path) -> None:
    """A refused model: a restart must not start with it."""
    (models_dir / RUNNING_FILE).unlink(missing_ok=True)


def last_running(models_dir: Path) -> tuple[FrameClassifier | None, Refusal | None]:
    """(the assigned model that ran before a restart, why it was refused). The model is checked
    against its manifest and against the registry's sha256 noted with it: a file that does not
    match is refused (never run) and the reason returned, so that the agent reports it. None
    and no reason: there is none, or it is unusable (the backend's assignment brings it back)."""
    marker = models_dir / RUNNING_FILE
    if not marker.is_file():
        return None, None
    version, _, registry_sha256 = marker.read_text().strip().partition(" ")
    try:
        classifier = FrameClassifier.from_dir(models_dir / version)
    except ModelIntegrityError as error:
        reason = f"model {version} refused at start: its file does not match its manifest"
        return None, Refusal(version, f"{reason} ({error})")
    except Exception as error:
        log.warning("model %s that ran before the restart is unusable: %s", version, error)
        return None, None
    if registry_sha256 and classifier.sha256 != registry_sha256:
        return None, Refusal(
            version,
            (
                f"model {version} refused at start: sha256 of its file is {classifier.sha256}, "
                f"the registry's is {registry_sha256}"
            ),
        )
    log.info("starting with model %s, assigned before the restart", version)
    return classifier, None


def load_initial_model(model_dir: Path | None) -> FrameClassifier | None:
    """The model the agent starts with (raises on a missing or tampered model)."""
    if model_dir is None:
        return None
    return FrameClassifier.from_dir(model_dir)

"""Model updates: download an assigned model, verify its sha256, swap it in between frames.

A file whose hash does not match the assignment and its manifest is refused and reported; the
running model keeps running.
"""

from __future__ import annotations

import hashlib
import json
import logging
import shutil
import threading
import urllib.request
from dataclasses import dataclass
from pathlib import Path

from vigil.model_file import MANIFEST_NAME, ModelIntegrityError, ModelManifest
from vigil.protocol import ModelAssignment
from vigil.runtime import FrameClassifier

log = logging.getLogger("robot_agent.models")


class ModelRefused(Exception):
    pass


@dataclass
class DownloadAuth:
    robot_id: str
    token: str


class ModelManager:
    """Holds the running classifier and, once verified, the next one to swap in."""

    def __init__(self, models_dir: Path | str, classifier: FrameClassifier | None = None) -> None:
        self.models_dir = Path(models_dir)
        self.classifier = classifier
        self._ready: FrameClassifier | None = None
        self._lock = threading.Lock()
        self.last_refusal: str | None = None

    @property
    def running_version(self) -> str | None:
        return self.classifier.manifest.version if self.classifier else None

    def swap_if_ready(self) -> bool:
        """Called by the frame loop between two frames."""
        with self._lock:
            ready, self._ready = self._ready, None
        if ready is None:
            return False
        old = self.running_version
        self.classifier = ready
        log.info("now running model %s (was %s)", ready.manifest.version, old)
        return True

    def install(self, assignment: ModelAssignment, auth: DownloadAuth) -> FrameClassifier:
        """Download and verify; on success the model is swapped in before the next frame.
        Raises ModelRefused (the running model stays) when anything does not match."""
        if assignment.version == self.running_version:
            return self.classifier  # type: ignore[return-value]
        try:
            manifest = ModelManifest.model_validate(assignment.manifest)
        except ValueError as error:
            raise self._refuse(assignment, f"manifest does not validate: {error}") from error
        if manifest.sha256 != assignment.sha256 or manifest.version != assignment.version:
            raise self._refuse(assignment, "assignment and manifest disagree on sha256 or version")
        request = urllib.request.Request(
            assignment.url,
            headers={"X-Robot-Id": auth.robot_id, "Authorization": f"Bearer {auth.token}"},
        )
        try:
            with urllib.request.urlopen(request, timeout=30) as response:
                data = response.read()
        except OSError as error:
            raise self._refuse(assignment, f"download failed: {error}") from error
        return self.install_bytes(assignment, manifest, data)

    def install_bytes(
        self, assignment: ModelAssignment, manifest: ModelManifest, data: bytes
    ) -> FrameClassifier:
        actual = hashlib.sha256(data).hexdigest()
        if actual != assignment.sha256:
            raise self._refuse(
                assignment, f"sha256 mismatch: expected {assignment.sha256}, got {actual}"
            )
        target = self.models_dir / _safe(assignment.version)
        staging = target.with_name(target.name + ".partial")
        shutil.rmtree(staging, ignore_errors=True)
        staging.mkdir(parents=True)
        (staging / manifest.file).write_bytes(data)
        (staging / MANIFEST_NAME).write_text(json.dumps(assignment.manifest))
        try:
            classifier = FrameClassifier.from_dir(staging)  # verifies the sha256 again
        except (ModelIntegrityError, ValueError) as error:
            shutil.rmtree(staging, ignore_errors=True)
            raise self._refuse(assignment, str(error)) from error
        shutil.rmtree(target, ignore_errors=True)
        staging.rename(target)
        with self._lock:
            self._ready = classifier
        log.info("model %s downloaded and verified; swapping it in", assignment.version)
        return classifier

    def _refuse(self, assignment: ModelAssignment, reason: str) -> ModelRefused:
        self.last_refusal = f"{assignment.version}: {reason}"[:256]
        log.error(
            "REFUSED model %s: %s; still running %s",
            assignment.version,
            reason,
            self.running_version,
        )
        return ModelRefused(self.last_refusal)


def _safe(version: str) -> str:
    return "".join(c if c.isalnum() or c in "-_." else "_" for c in version).strip(".") or "model"

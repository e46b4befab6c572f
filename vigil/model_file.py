"""Model files: an ONNX graph plus a JSON manifest; the graph's sha256 is checked before loading.

Nothing is ever unpickled: the only executable format is ONNX, run by ONNX Runtime on one CPU
thread. The classifier returns class probabilities in the manifest's class order.
"""

from __future__ import annotations

import hashlib
from datetime import UTC, datetime
from pathlib import Path
from typing import Any, Literal

import numpy as np
from pydantic import BaseModel, ConfigDict, Field, field_validator, model_validator

from vigil.classes import MODE_CLASSES, Decision, TransportMode
from vigil.inputs import InputName, model_inputs, normalise

MANIFEST_NAME = "manifest.json"
MODEL_NAME = "model.onnx"


class ModelIntegrityError(Exception):
    """The model file does not match the sha256 recorded in its manifest."""

    def __init__(self, path: Path, expected: str, actual: str) -> None:
        super().__init__(f"{path}: sha256 mismatch, expected {expected}, actual {actual}")
        self.path, self.expected, self.actual = path, expected, actual


class ModelManifest(BaseModel):
    model_config = ConfigDict(extra="forbid", protected_namespaces=())

    version: str = Field(min_length=1)
    created: datetime = Field(default_factory=lambda: datetime.now(UTC))
    name: str = Field(default="model", description="model configuration, e.g. svm-paper")
    mode: TransportMode
    classes: list[Decision]
    feature_version: int
    feature_set: str = "full"
    window: int = Field(default=1, ge=1, description="frames of features per inference")
    inputs: list[InputName] = Field(
        default_factory=list,
        description="what the model needs in every frame (vigil.inputs); derived from "
        "feature_set for manifests written before the field existed",
    )
    taxonomy_version: int
    threshold: float = Field(ge=0.0, le=1.0)
    delay_ms: int = Field(ge=0, le=10_000)
    metrics: dict[str, Any] = Field(default_factory=dict)
    training_data_sha256: str
    generated_data: bool = Field(default=False, description="trained on generated, not real data")
    file: str = MODEL_NAME
    sha256: str = Field(pattern=r"^[0-9a-f]{64}$")
    format: Literal["onnx"] = "onnx"

    @property
    def training_recordings(self) -> list[str] | None:
        """Names of the recordings the model was fitted on (None: not recorded, e.g. a model
        made elsewhere); the promotion gate refuses a gold set that overlaps them. Kept in
        `metrics`, not as a field of its own: agents of earlier releases refuse a manifest
        with a field they do not know (extra="forbid"), and a fleet upgrades robot by robot."""
        names = self.metrics.get("training_recordings")
        return list(names) if names is not None else None

    @field_validator("file")
    @classmethod
    def _plain_file_name(cls, value: str) -> str:
        if "/" in value or "\\" in value or value in ("", ".", ".."):
            raise ValueError("file must be a plain file name next to the manifest")
        return value

    @model_validator(mode="after")
    def _inputs_known(self) -> ModelManifest:
        inputs = normalise(self.inputs) if self.inputs else model_inputs(self.feature_set)
        self.inputs = inputs
        return self

    @model_validator(mode="after")
    def _classes_match_mode(self) -> ModelManifest:
        if tuple(self.classes) != MODE_CLASSES[self.mode]:
            expected = [c.value for c in MODE_CLASSES[self.mode]]
            raise ValueError(f"classes for mode {self.mode.value} must be {expected}")
        return self


def sha256_hex(data: bytes) -> str:
    return hashlib.sha256(data).hexdigest()


def write_model(directory: Path | str, onnx_bytes: bytes, manifest: ModelManifest) -> Path:
    """Write the ONNX file and its manifest (sha256 filled in from the bytes); returns the dir."""
    directory = Path(directory)
    directory.mkdir(parents=True, exist_ok=True)
    manifest = manifest.model_copy(update={"sha256": sha256_hex(onnx_bytes)})
    (directory / manifest.file).write_bytes(onnx_bytes)
    (directory / MANIFEST_NAME).write_text(manifest.model_dump_json(indent=2))
    return directory


def read_manifest(path: Path | str) -> tuple[ModelManifest, Path]:
    path = Path(path)
    manifest_path = path / MANIFEST_NAME if path.is_dir() else path
    manifest = ModelManifest.model_validate_json(manifest_path.read_text())
    return manifest, manifest_path.parent


class Classifier:
    """ONNX Runtime session returning (n, k) class probabilities in manifest class order."""

    def __init__(self, manifest: ModelManifest, onnx_bytes: bytes) -> None:
        import onnxruntime as ort

        options = ort.SessionOptions()
        options.intra_op_num_threads = 1
        options.inter_op_num_threads = 1
        options.log_severity_level = 3
        self.manifest = manifest
        self.sha256 = sha256_hex(onnx_bytes)  # of the bytes this session runs
        self._session = ort.InferenceSession(
            onnx_bytes, sess_options=options, providers=["CPUExecutionProvider"]
        )
        self._input = self._session.get_inputs()[0].name
        outputs = [o.name for o in self._session.get_outputs()]
        self._output = "probabilities" if "probabilities" in outputs else outputs[-1]

    def predict_proba(self, features: np.ndarray) -> np.ndarray:
        features = np.ascontiguousarray(features, dtype=np.float32)
        (probabilities,) = self._session.run([self._output], {self._input: features})
        probabilities = np.asarray(probabilities, np.float32)
        if probabilities.shape[-1] != len(self.manifest.classes):
            raise ValueError(
                f"model returned {probabilities.shape[-1]} scores for "
                f"{len(self.manifest.classes)} classes"
            )
        return probabilities


def load_classifier(path: Path | str) -> Classifier:
    """Load from a model directory or its manifest path, verifying the sha256 first."""
    manifest, directory = read_manifest(path)
    model_path = directory / manifest.file
    data = model_path.read_bytes()
    actual = sha256_hex(data)
    if actual != manifest.sha256:
        raise ModelIntegrityError(model_path, manifest.sha256, actual)
    return Classifier(manifest, data)

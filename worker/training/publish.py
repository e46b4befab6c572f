"""Turn a selected, fitted model into an ONNX file + manifest (verified against Python)."""

from __future__ import annotations

from datetime import UTC, datetime
from pathlib import Path

import numpy as np

from vigil.features import FEATURE_NAMES, FEATURE_VERSION
from vigil.inputs import model_inputs
from vigil.model_file import ModelManifest, read_manifest, write_model
from vigil.taxonomy import DEFAULT_TAXONOMY
from worker.training.cross_validation import Selected
from worker.training.data import FrameData
from worker.training.export import verify_export
from worker.training.trainers import Trainer


def publish(
    trainer: Trainer,
    selected: Selected,
    data: FrameData,
    out_dir: Path | str,
    version: str | None = None,
    metrics: dict | None = None,
) -> ModelManifest:
    onnx_bytes = trainer.to_onnx(selected.fitted, data)
    manifest = ModelManifest(
        version=version or f"{trainer.name}-{datetime.now(UTC):%Y%m%dT%H%M%S}",
        name=trainer.name,
        mode=data.mode,
        classes=list(data.classes),
        feature_version=FEATURE_VERSION,
        feature_set=trainer.feature_set,
        window=trainer.window_of(selected.fitted),
        inputs=model_inputs(trainer.feature_set, fitted_with_depth(data)),
        taxonomy_version=DEFAULT_TAXONOMY.version,
        threshold=selected.threshold,
        delay_ms=int(round(selected.delay_s * 1000)),
        metrics={
            "params": {k: _plain(v) for k, v in selected.params.items()},
            "training_rows": int(len(data.target)),
            "training_recordings": list(data.names),
            **(metrics or {}),
        },
        training_data_sha256=data.data_sha256,
        generated_data=data.generated,
        sha256="0" * 64,
    )
    sample, expected = trainer.reference(selected.fitted, data, 256)
    verify_export(onnx_bytes, manifest, sample, expected)
    write_model(out_dir, onnx_bytes, manifest)
    return read_manifest(out_dir)[0]


def fitted_with_depth(data: FrameData) -> bool:
    """Most frames a model is fitted on had depth at the keypoints: it needs depth to run."""
    if data.features.shape[1] != len(FEATURE_NAMES):
        raise ValueError("FrameData must hold the full feature set")
    has_depth = data.features[data.trainable, FEATURE_NAMES.index("has_depth")]
    return bool(has_depth.size and np.mean(has_depth > 0) > 0.5)


def _plain(value):
    return list(value) if isinstance(value, tuple) else value

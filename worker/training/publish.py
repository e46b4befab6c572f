"""Turn a selected, fitted model into an ONNX file + manifest (verified against Python)."""

from __future__ import annotations

from datetime import UTC, datetime
from pathlib import Path

from vigil.features import FEATURE_VERSION
from vigil.model_file import ModelManifest, write_model
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
        window=trainer.window,
        taxonomy_version=DEFAULT_TAXONOMY.version,
        threshold=selected.threshold,
        delay_ms=int(round(selected.delay_s * 1000)),
        metrics={"params": {k: _plain(v) for k, v in selected.params.items()}, **(metrics or {})},
        training_data_sha256=data.data_sha256,
        generated_data=data.generated,
        sha256="0" * 64,
    )
    sample, expected = trainer.reference(selected.fitted, data, 256)
    verify_export(onnx_bytes, manifest, sample, expected)
    write_model(out_dir, onnx_bytes, manifest)
    from vigil.model_file import read_manifest

    return read_manifest(out_dir)[0]


def _plain(value):
    return list(value) if isinstance(value, tuple) else value

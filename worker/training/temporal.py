"""A temporal 1D-CNN over a window of recent per-frame feature vectors (torch, CPU, ONNX export).

Input: (batch, window, n_features) raw features; the standardisation learned on the training
frames is part of the network, so the ONNX graph takes the extractor's output as it is.
"""

from __future__ import annotations

import io
from typing import Any

import numpy as np
import torch
from torch import nn

from vigil.features import FEATURE_SETS, window_index
from worker.training.data import FrameData
from worker.training.trainers import training_rows


class TemporalCNN(nn.Module):
    def __init__(self, n_features: int, n_classes: int, channels: int, dropout: float) -> None:
        super().__init__()
        self.register_buffer("mean", torch.zeros(n_features))
        self.register_buffer("std", torch.ones(n_features))
        self.net = nn.Sequential(
            nn.Conv1d(n_features, channels, kernel_size=5, padding=2),
            nn.ReLU(),
            nn.Dropout(dropout),
            nn.Conv1d(channels, channels, kernel_size=5, padding=4, dilation=2),
            nn.ReLU(),
        )
        self.head = nn.Sequential(nn.Dropout(dropout), nn.Linear(2 * channels, n_classes))

    def forward(self, windows: torch.Tensor) -> torch.Tensor:
        """(batch, window, features) -> logits (batch, classes)."""
        x = ((windows - self.mean) / self.std).transpose(1, 2)
        h = self.net(x)
        pooled = torch.cat([h.amax(dim=2), h[:, :, -1]], dim=1)
        return self.head(pooled)


class _Probabilities(nn.Module):
    def __init__(self, model: TemporalCNN) -> None:
        super().__init__()
        self.model = model

    def forward(self, windows: torch.Tensor) -> torch.Tensor:
        return torch.softmax(self.model(windows), dim=1)


class TemporalTrainer:
    """Trainer protocol (see trainers.py) for TemporalCNN; one measured configuration."""

    operating_point = "event"  # see worker.training.selection.choose_operating_point

    def __init__(
        self,
        name: str = "tcn",
        window: int = 24,
        channels: int = 48,
        epochs: int = 10,
        dropout: float = 0.2,
        learning_rate: float = 2e-3,
        weight_decay: float = 1e-3,
        batch_size: int = 256,
        feature_set: str = "full",
        threads: int = 1,
        seed: int = 0,
    ) -> None:
        self.name, self.window, self.channels, self.epochs = name, window, channels, epochs
        self.dropout, self.learning_rate, self.weight_decay = dropout, learning_rate, weight_decay
        self.batch_size, self.feature_set, self.threads, self.seed = (
            batch_size,
            feature_set,
            threads,
            seed,
        )

    @property
    def columns(self) -> np.ndarray:
        return FEATURE_SETS[self.feature_set]

    def configurations(self) -> list[dict[str, Any]]:
        return [
            {
                "window": self.window,
                "channels": self.channels,
                "epochs": self.epochs,
                "dropout": self.dropout,
            }
        ]

    def _inputs(self, data: FrameData) -> tuple[torch.Tensor, np.ndarray]:
        features = torch.from_numpy(np.ascontiguousarray(data.features[:, self.columns]))
        return features, window_index(data.group, self.window)

    def fit(self, data: FrameData, sequences: np.ndarray, params: dict, stride: int = 1):
        torch.manual_seed(self.seed)
        torch.set_num_threads(self.threads)
        features, index = self._inputs(data)
        # 30 frames/s are redundant for a window model: every other frame is plenty.
        rows = training_rows(data, sequences, max(stride, 2))
        target = torch.from_numpy(data.fit_target[rows].astype(np.int64))
        model = TemporalCNN(
            features.shape[1], len(data.classes), params["channels"], params["dropout"]
        )
        train_frames = features[rows]
        model.mean.copy_(train_frames.mean(dim=0))
        model.std.copy_(train_frames.std(dim=0).clamp_min(1e-3))
        counts = torch.bincount(target, minlength=len(data.classes)).float().clamp_min(1)
        loss_fn = nn.CrossEntropyLoss(weight=counts.sum() / (len(counts) * counts))
        optimiser = torch.optim.AdamW(
            model.parameters(), lr=self.learning_rate, weight_decay=self.weight_decay
        )
        steps = params["epochs"] * int(np.ceil(len(rows) / self.batch_size))
        schedule = torch.optim.lr_scheduler.OneCycleLR(
            optimiser, self.learning_rate, total_steps=steps
        )
        generator = torch.Generator().manual_seed(self.seed)
        index_t = torch.from_numpy(index[rows])
        model.train()
        for _ in range(params["epochs"]):
            for batch in torch.randperm(len(rows), generator=generator).split(self.batch_size):
                windows = features[index_t[batch]]
                loss = loss_fn(model(windows), target[batch])
                optimiser.zero_grad()
                loss.backward()
                optimiser.step()
                schedule.step()
        model.eval()
        return model

    def _predict(self, model: TemporalCNN, features, index_rows) -> np.ndarray:
        out = []
        with torch.no_grad():
            for batch in torch.from_numpy(index_rows).split(2048):
                out.append(torch.softmax(model(features[batch]), dim=1).numpy())
        return np.concatenate(out) if out else np.zeros((0, 2))

    def score(self, fitted, data: FrameData, sequences: np.ndarray) -> np.ndarray:
        features, index = self._inputs(data)
        return self._predict(fitted, features, index[data.frames_of(sequences)])

    def to_onnx(self, fitted, data: FrameData) -> bytes:
        buffer = io.BytesIO()
        example = torch.zeros(1, self.window, len(self.columns))
        torch.onnx.export(
            _Probabilities(fitted).eval(),
            (example,),
            buffer,
            input_names=["windows"],
            output_names=["probabilities"],
            dynamic_axes={"windows": {0: "batch"}, "probabilities": {0: "batch"}},
            dynamo=False,
        )
        return buffer.getvalue()

    def reference(self, fitted, data: FrameData, n: int = 256):
        features, index = self._inputs(data)
        rows = np.flatnonzero(data.trainable)
        rows = rows[np.linspace(0, len(rows) - 1, min(n, len(rows))).astype(int)]
        return features[index[rows]].numpy(), self._predict(fitted, features, index[rows])

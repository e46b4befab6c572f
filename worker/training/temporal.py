"""A temporal 1D-CNN over a window of recent per-frame feature vectors (torch, CPU, ONNX export).

Input: (batch, window, n_features) raw features; the standardisation learned on the training
frames is part of the network, so the ONNX graph takes the extractor's output as it is.

`TemporalClassifier` is the scikit-learn estimator (fit(X, y, groups) returns self, learns
`model_`): the family `tcn` (worker.training.estimators.FAMILIES), which EmergencyDetector
selects like any other family (grid, inner cross-validation, threshold and delay); `to_onnx`
exports it.
"""

from __future__ import annotations

import io

import numpy as np
import torch
from sklearn.base import BaseEstimator, ClassifierMixin
from sklearn.utils.multiclass import check_classification_targets
from sklearn.utils.validation import check_is_fitted, validate_data
from torch import nn

from vigil.features import window_index


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


class TemporalClassifier(ClassifierMixin, BaseEstimator):
    """TemporalCNN as a scikit-learn classifier of frames in their streams.

    fit(X, y, groups): X (n, n_features) per-frame features of whole streams in time order,
    y each frame's class index (< 0: not trained on, still a window's context), groups each
    frame's stream (None: one stream). Every `stride`-th trainable frame is trained on.
    `n_classes` fixes the number of outputs (a transport mode's classes, present or not in y;
    None: the classes in y).
    predict_proba(X, groups) scores each frame on its last `window` frames of its stream.
    Learned: `model_` (TemporalCNN, eval mode), `classes_`, `n_features_in_`.
    """

    #: A frame is scored on the frames before it in its stream: fit and predict_proba take the
    #: frames' `groups` (worker.training.estimators.takes_streams).
    takes_streams = True

    def __init__(
        self,
        window: int = 24,
        channels: int = 48,
        epochs: int = 10,
        dropout: float = 0.2,
        learning_rate: float = 2e-3,
        weight_decay: float = 1e-3,
        batch_size: int = 256,
        stride: int = 2,
        n_classes: int | None = None,
        threads: int = 1,
        seed: int = 0,
    ) -> None:
        self.n_classes = n_classes
        self.window, self.channels, self.epochs, self.dropout = window, channels, epochs, dropout
        self.learning_rate, self.weight_decay = learning_rate, weight_decay
        self.batch_size, self.stride, self.threads, self.seed = batch_size, stride, threads, seed

    def fit(self, X, y, groups=None):
        X, y = validate_data(self, X, y, dtype=np.float32)
        check_classification_targets(y)
        y = np.asarray(y).astype(np.int64)
        trained = y >= 0
        if not trained.any():
            raise ValueError("y has no frame to train on (every class index is negative)")
        self.classes_ = np.arange(self.n_classes or int(y.max()) + 1)
        if len(self.classes_) < 2:
            raise ValueError("y holds one class: a classifier needs at least two classes")
        torch.manual_seed(self.seed)
        torch.set_num_threads(self.threads)
        features = torch.from_numpy(np.ascontiguousarray(X))
        index = window_index(_streams(groups, len(X)), self.window)
        rows = np.flatnonzero(trained)[:: self.stride]
        target = torch.from_numpy(y[rows])
        n_classes = len(self.classes_)
        model = TemporalCNN(features.shape[1], n_classes, self.channels, self.dropout)
        train_frames = features[rows]
        model.mean.copy_(train_frames.mean(dim=0))
        model.std.copy_(train_frames.std(dim=0).nan_to_num(1.0).clamp_min(1e-3))
        counts = torch.bincount(target, minlength=n_classes).float().clamp_min(1)
        loss_fn = nn.CrossEntropyLoss(weight=counts.sum() / (len(counts) * counts))
        optimiser = torch.optim.AdamW(
            model.parameters(), lr=self.learning_rate, weight_decay=self.weight_decay
        )
        steps = self.epochs * int(np.ceil(len(rows) / self.batch_size))
        schedule = torch.optim.lr_scheduler.OneCycleLR(
            optimiser, self.learning_rate, total_steps=max(steps, 1)
        )
        generator = torch.Generator().manual_seed(self.seed)
        index_t = torch.from_numpy(index[rows])
        model.train()
        for _ in range(self.epochs):
            for batch in torch.randperm(len(rows), generator=generator).split(self.batch_size):
                windows = features[index_t[batch]]
                loss = loss_fn(model(windows), target[batch])
                optimiser.zero_grad()
                loss.backward()
                optimiser.step()
                schedule.step()
        self.model_ = model.eval()
        return self

    def windows(self, X, groups=None) -> np.ndarray:
        """(n, window, n_features) the network's input for each frame."""
        check_is_fitted(self, "model_")
        X = validate_data(self, X, dtype=np.float32, reset=False)
        return X[window_index(_streams(groups, len(X)), self.window)]

    def predict_proba(self, X, groups=None) -> np.ndarray:
        check_is_fitted(self, "model_")
        X = validate_data(self, X, dtype=np.float32, reset=False)
        features = torch.from_numpy(np.ascontiguousarray(X))
        index = window_index(_streams(groups, len(X)), self.window)
        out = []
        with torch.no_grad():
            for batch in torch.from_numpy(index).split(2048):
                out.append(torch.softmax(self.model_(features[batch]), dim=1).numpy())
        return np.concatenate(out) if out else np.zeros((0, len(self.classes_)))

    def predict(self, X, groups=None) -> np.ndarray:
        scores = self.predict_proba(X, groups)
        return self.classes_[np.argmax(scores, axis=1)]


def _streams(groups, n: int) -> np.ndarray:
    return np.zeros(n, np.int64) if groups is None else np.asarray(groups)


def to_onnx(classifier: TemporalClassifier) -> bytes:
    """The fitted classifier's network as an ONNX graph: input `windows` (batch, window,
    n_features) of raw features, output `probabilities` (batch, classes)."""
    check_is_fitted(classifier, "model_")
    buffer = io.BytesIO()
    example = torch.zeros(1, classifier.window, classifier.n_features_in_)
    torch.onnx.export(
        _Probabilities(classifier.model_).eval(),
        (example,),
        buffer,
        input_names=["windows"],
        output_names=["probabilities"],
        dynamic_axes={"windows": {0: "batch"}, "probabilities": {0: "batch"}},
        dynamo=False,
    )
    return buffer.getvalue()

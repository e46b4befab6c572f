"""Fitted scikit-learn pipelines -> ONNX graphs whose `probabilities` output is in class order."""

from __future__ import annotations

import numpy as np
import onnx
from onnx import TensorProto, helper
from skl2onnx import to_onnx
from sklearn.pipeline import Pipeline
from sklearn.svm import SVC

from vigil.model_file import Classifier, ModelManifest


def _sigmoid_head(model: onnx.ModelProto, column: int, sign: float) -> onnx.ModelProto:
    """Replace a binary SVC's decision values by [1 - p, p] with p = sigmoid(decision)."""
    graph = model.graph
    scores = next(o for o in graph.output if o.name == "probabilities")
    scores.name = "svm_scores"
    for node in graph.node:
        node.output[:] = ["svm_scores" if o == "probabilities" else o for o in node.output]
    graph.initializer.extend(
        [
            helper.make_tensor("svm_col", TensorProto.INT64, [1], [column]),
            helper.make_tensor("svm_sign", TensorProto.FLOAT, [1], [sign]),
            helper.make_tensor("svm_one", TensorProto.FLOAT, [1], [1.0]),
        ]
    )
    graph.node.extend(
        [
            helper.make_node("Gather", ["svm_scores", "svm_col"], ["svm_f"], axis=1),
            helper.make_node("Mul", ["svm_f", "svm_sign"], ["svm_signed"]),
            helper.make_node("Sigmoid", ["svm_signed"], ["svm_p1"]),
            helper.make_node("Sub", ["svm_one", "svm_p1"], ["svm_p0"]),
            helper.make_node("Concat", ["svm_p0", "svm_p1"], ["probabilities"], axis=1),
        ]
    )
    del graph.output[:]
    graph.output.extend(
        [helper.make_tensor_value_info("probabilities", TensorProto.FLOAT, [None, 2])]
    )
    return model


def sklearn_to_onnx(pipeline: Pipeline, sample: np.ndarray) -> bytes:
    sample = np.asarray(sample[:64], np.float32)
    estimator = pipeline.steps[-1][1]
    model = to_onnx(pipeline, sample[:1], options={id(estimator): {"zipmap": False}})
    if isinstance(estimator, SVC):
        # skl2onnx emits decision values for an SVC without probability; find the column (and
        # its sign) that equals sklearn's decision_function, then squash it like our scorer does.
        import onnxruntime as ort

        session = ort.InferenceSession(
            model.SerializeToString(), providers=["CPUExecutionProvider"]
        )
        raw = session.run(["probabilities"], {session.get_inputs()[0].name: sample})[0]
        reference = pipeline.decision_function(sample)
        column, sign = min(
            ((c, s) for c in range(raw.shape[1]) for s in (1.0, -1.0)),
            key=lambda cs: np.abs(cs[1] * raw[:, cs[0]] - reference).max(),
        )
        model = _sigmoid_head(model, column, sign)
    return model.SerializeToString()


def verify_export(onnx_bytes: bytes, manifest: ModelManifest, sample, expected) -> float:
    """Largest difference between ONNX Runtime and the Python model; raises if above 1e-3."""
    classifier = Classifier(manifest, onnx_bytes)
    got = classifier.predict_proba(np.asarray(sample, np.float32))
    worst = float(np.abs(got - np.asarray(expected)).max())
    if worst > 1e-3:
        raise RuntimeError(f"ONNX export differs from the trained model by {worst:.4g}")
    return worst

"""PNG plots: ROC and precision-recall with default and chosen thresholds, metrics over delay."""

from __future__ import annotations

from pathlib import Path

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402
import numpy as np  # noqa: E402

from vigil.thresholds import DEFAULT_GRID, binary_counts  # noqa: E402


def _curve(scores, positive):
    c = binary_counts(scores, positive, DEFAULT_GRID)
    tpr = c["tp"] / max(c["tp"][0] + c["fn"][0], 1)
    fpr = c["fp"] / max(c["fp"][0] + c["tn"][0], 1)
    precision = np.divide(
        c["tp"], c["tp"] + c["fp"], out=np.ones(len(DEFAULT_GRID)), where=(c["tp"] + c["fp"]) > 0
    )
    return fpr, tpr, precision


def roc_pr(scores, positive, chosen: float, title: str, path: Path, default: float = 0.5) -> None:
    fpr, tpr, precision = _curve(scores, positive)
    fig, (roc, pr) = plt.subplots(1, 2, figsize=(10, 4.5))
    roc.plot(fpr, tpr, color="tab:blue")
    roc.plot([0, 1], [0, 1], color="grey", linestyle=":")
    pr.plot(tpr, precision, color="tab:blue")
    for value, label, style in ((default, "default", "s"), (chosen, "chosen", "o")):
        k = int(np.argmin(np.abs(DEFAULT_GRID - value)))
        roc.plot(fpr[k], tpr[k], style, markersize=9, label=f"{label} t={value:.3f}")
        pr.plot(tpr[k], precision[k], style, markersize=9, label=f"{label} t={value:.3f}")
    roc.set(xlabel="false positive rate", ylabel="recall (true positive rate)", title="ROC")
    pr.set(xlabel="recall", ylabel="precision", title="precision-recall")
    for ax in (roc, pr):
        ax.legend(loc="lower right" if ax is roc else "lower left")
        ax.grid(alpha=0.3)
    fig.suptitle(title)
    fig.tight_layout()
    fig.savefig(path, dpi=90)
    plt.close(fig)


def delay_metrics(sweep: dict, chosen_s: float, title: str, path: Path) -> None:
    delay = np.asarray(sweep["delay_s"])
    fig, (f1, counts) = plt.subplots(1, 2, figsize=(10, 4))
    f1.plot(delay, sweep["event_f1"], label="event F1")
    f1.plot(delay, sweep["frame_f1_filtered"], label="frame F1 after delay")
    counts.plot(delay, sweep["falls_detected"], label="falls detected")
    counts.plot(delay, sweep["false_alarm_sequences"], label="sequences with a false alarm")
    for ax in (f1, counts):
        ax.axvline(
            chosen_s, color="black", linestyle="--", label=f"chosen {chosen_s * 1000:.0f} ms"
        )
        ax.set_xlabel("delay (s)")
        ax.grid(alpha=0.3)
        ax.legend()
    fig.suptitle(title)
    fig.tight_layout()
    fig.savefig(path, dpi=90)
    plt.close(fig)

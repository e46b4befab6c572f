"""Shared mapping helper: place source keypoints into BODY_25 slots."""

from __future__ import annotations

import numpy as np

from vigil.skeleton import INDEX, N_KEYPOINTS


def map_to_body25(xyc: np.ndarray, names: tuple[str | None, ...]) -> np.ndarray:
    """(n, k, 3) source keypoints named by `names` (None = no BODY_25 counterpart) -> (n, 25, 3).

    Keypoints without a counterpart stay missing (confidence 0). OpenPose derives neck and mid_hip
    from the shoulders and hips; when the source lacks them they are derived the same way,
    with the lower confidence of the two parents.
    """
    xyc = np.asarray(xyc, dtype=np.float32)
    out = np.zeros((xyc.shape[0], N_KEYPOINTS, 3), np.float32)
    for source_index, name in enumerate(names):
        if name is not None:
            out[:, INDEX[name]] = xyc[:, source_index]
    out[out[:, :, 2] <= 0] = 0.0  # a missing keypoint carries no coordinates
    for derived, (a, b) in (
        ("neck", ("r_shoulder", "l_shoulder")),
        ("mid_hip", ("r_hip", "l_hip")),
    ):
        if derived in names:
            continue
        pa, pb = out[:, INDEX[a]], out[:, INDEX[b]]
        both = (pa[:, 2] > 0) & (pb[:, 2] > 0)
        out[both, INDEX[derived], :2] = (pa[both, :2] + pb[both, :2]) / 2
        out[both, INDEX[derived], 2] = np.minimum(pa[both, 2], pb[both, 2])
    return out


def scale_xy(xyc: np.ndarray, image_size: tuple[float, float] | None) -> np.ndarray:
    """Normalised (0..1) coordinates -> pixels when image_size (width, height) is given."""
    if image_size is None:
        return xyc
    xyc = np.array(xyc, dtype=np.float32, copy=True)
    xyc[..., 0] *= image_size[0]
    xyc[..., 1] *= image_size[1]
    return xyc

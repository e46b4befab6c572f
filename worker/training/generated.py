"""FrameData from GENERATED transports (wheelchair and combined modes; URFD has no such data)."""

from __future__ import annotations

import hashlib

import numpy as np

from vigil.classes import MODE_CLASSES, Decision, TransportMode
from vigil.features import extract_arrays
from vigil.synthetic_transports import class_targets, generate_transports
from worker.training.data import FrameData


def generated_frames(mode: TransportMode | str, repeats: int = 8, seed: int = 0) -> FrameData:
    mode = TransportMode(mode)
    sequences = generate_transports(mode, repeats, seed)
    emergency = MODE_CLASSES[mode].index(Decision.EMERGENCY)
    feats, targets, groups, times, positive = [], [], [], [], []
    digest = hashlib.sha256()
    for i, seq in enumerate(sequences):
        feats.append(extract_arrays(seq.keypoints, seq.depth, seq.timestamps))
        target = class_targets(seq, mode)
        targets.append(target)
        groups.append(np.full(len(target), i))
        times.append(seq.timestamps)
        positive.append(bool(np.any(target == emergency)))
        digest.update(seq.keypoints.tobytes())
    return FrameData(
        names=[s.name for s in sequences],
        is_positive_sequence=np.array(positive),
        features=np.concatenate(feats),
        target=np.concatenate(targets),
        group=np.concatenate(groups),
        timestamps=np.concatenate(times),
        usable=np.ones(sum(len(t) for t in targets), bool),
        mode=mode,
        data_sha256=digest.hexdigest(),
        generated=True,
    )

"""Cyclic garbage collector settings for the backend process (the ingest hot path).

Ingest allocates containers fast enough (pydantic's nested keypoint lists) to trigger a full
collection every few seconds, and a full collection walks every tracked object, start-up's
modules, classes and ORM metadata (~180k objects) included: a quarter of the ingest CPU.
Those objects are never garbage, so they are frozen (moved out of the collector's sight) while
the app runs. And the young generation is collected after 20,000 net allocations instead of
700: a 50-frame batch alone holds ~1,500 containers, so the default collected several times
per message, promoting in-flight batches to the older generations to be walked again.
"""

from __future__ import annotations

import gc
from collections.abc import Iterator
from contextlib import contextmanager

COLLECT_AFTER = (20_000, 10, 10)  # gc.set_threshold: net allocations, then young collections


@contextmanager
def collector_tuned_for_ingest() -> Iterator[None]:
    gc.collect()  # garbage left by start-up would otherwise be frozen too, for good
    gc.freeze()
    defaults = gc.get_threshold()
    gc.set_threshold(*COLLECT_AFTER)
    try:
        yield
    finally:
        gc.set_threshold(*defaults)
        gc.unfreeze()

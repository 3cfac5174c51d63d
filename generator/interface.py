"""The interface every image-to-articulated-object generator implements.

``pact convert`` drives any of them the same way: PAct (``generator.pact``) and the
retrieval baseline (``generator.retrieval``).
"""

from __future__ import annotations

from typing import Any, Protocol, runtime_checkable

import numpy as np

from generator.articulated import ArticulatedObject


@runtime_checkable
class Generator(Protocol):
    """Image (+ optional part mask, + hints) -> ArticulatedObject.

    image: (H, W, 3) uint8 RGB. mask: (H, W) uint8 part ids (0 background, 1 base,
    2.. movable parts) or None. hints: optional dict (``category``, ``height`` in
    metres, ...; see docs/input-format.md). The returned object follows the frame
    convention; ``scale`` is None when the generator does not know metric size.
    ``timings`` (seconds per stage of the last call) and ``name``/``version`` are
    recorded in the catalog.
    """

    name: str
    version: str
    timings: dict[str, float]

    def generate(
        self,
        image: np.ndarray,
        mask: np.ndarray | None = None,
        hints: dict[str, Any] | None = None,
    ) -> ArticulatedObject: ...

"""The procedural factory: seeded, metric articulated furniture and appliances.

``sample_object(category, seed, split)`` returns an ``ArticulatedObject`` (scale 1.0,
metres; +z up, front faces +x, origin at the centre of the base footprint on the
floor) whose parts are unions of boxes and cylinders (``Part.primitives``) with
watertight meshes, vertex colours or small procedural textures, handles that
belong to their movable parts, and joints that open outward (positive values).

Determinism: the same ``(category, seed, split)`` always gives the same object;
the generator is ``numpy.random.default_rng`` seeded by SHA-256 of the triple.

Held-out test ranges (``split="test"`` draws these ONLY from the held-out part;
``split="train"`` never draws from it; see ``HELD_OUT``):

================  ====================  ===========================
category          parameter             full range / held-out part
================  ====================  ===========================
cabinet           width (m)             0.40-1.60 / 0.90-1.00
cabinet           height (m)            0.45-2.00 / 1.10-1.25
cabinet           columns               train 1, 2 / test 3
desk              width (m)             0.90-1.80 / 1.25-1.35
desk              n_drawers             train 1, 2, 4 / test 3
microwave         width (m)             0.44-0.62 / 0.52-0.54
microwave         aspect (h / w)        0.50-0.70 / 0.59-0.62
oven              width, height (m)     0.50-0.90 / 0.66-0.72; 0.82-0.95 / 0.87-0.89
dishwasher        width, height (m)     0.44-0.62 / 0.52-0.55; 0.80-0.88 / 0.835-0.85
refrigerator      width, height (m)     0.55-0.95 / 0.70-0.76; 1.40-1.95 / 1.62-1.70
washing_machine   width, height (m)     0.55-0.65 / 0.595-0.61; 0.82-0.92 / 0.86-0.875
================  ====================  ===========================

(Cabinet ``columns`` is reduced to fit narrow widths; the recorded value is the one
used.) All drawn parameters are recorded in ``provenance["params"]``.

Modules: ``sampling`` (seeded recorded draws, split ranges), ``solids`` (boxes,
cylinders, manifold union), ``appearance`` (colours, textures), ``blocks``
(carcass, drawer, door, lid, handle builders), ``assembly`` (part specs to an
object), ``furniture`` (cabinet, desk), ``appliances`` (the five appliances).
"""

from __future__ import annotations

import logging
from collections.abc import Callable

from generator.articulated import ArticulatedObject
from generator.procedural import appliances, furniture
from generator.procedural.assembly import PartSpec, assemble
from generator.procedural.sampling import SPLITS, ParamSampler, SplitChoice, SplitRange

__all__ = [
    "CATEGORIES",
    "HELD_OUT",
    "UnknownCategoryError",
    "object_id",
    "sample_object",
]

log = logging.getLogger(__name__)

CATEGORIES: tuple[str, ...] = (
    "cabinet",
    "desk",
    "microwave",
    "oven",
    "dishwasher",
    "refrigerator",
    "washing_machine",
)

_BUILDERS: dict[str, Callable[[ParamSampler], tuple[PartSpec, list[PartSpec]]]] = {
    "cabinet": furniture.cabinet,
    "desk": furniture.desk,
    "microwave": appliances.microwave,
    "oven": appliances.oven,
    "dishwasher": appliances.dishwasher,
    "refrigerator": appliances.refrigerator,
    "washing_machine": appliances.washing_machine,
}

#: Per category, the split parameters: name -> SplitRange (floats) or SplitChoice (ints).
HELD_OUT: dict[str, dict[str, SplitRange | SplitChoice]] = {**furniture.SPLITS, **appliances.SPLITS}


class UnknownCategoryError(ValueError):
    """The category is not one the procedural factory makes."""

    def __init__(self, category: str) -> None:
        super().__init__(
            f"unknown category {category!r}; valid categories: {', '.join(CATEGORIES)}"
        )
        self.category = category


def _check(category: str, split: str) -> None:
    if category not in _BUILDERS:
        raise UnknownCategoryError(category)
    if split not in SPLITS:
        raise ValueError(f"split must be one of {SPLITS}, got {split!r}")


def object_id(category: str, seed: int, split: str = "train") -> str:
    """Stable id of a procedural object: ``cabinet_s0000012`` (train), ``cabinet_t0000012`` (test)."""
    _check(category, split)
    return f"{category}_{'s' if split == 'train' else 't'}{int(seed):07d}"


def sample_object(category: str, seed: int, split: str = "train") -> ArticulatedObject:
    """The procedural object of ``category`` for ``seed`` and ``split`` ("train" or "test").

    Raises UnknownCategoryError for a category not in CATEGORIES and ValueError for a
    split other than "train" / "test".
    """
    _check(category, split)
    sampler = ParamSampler(category, seed, split)
    base, movable = _BUILDERS[category](sampler)
    provenance = {
        "generator": "procedural",
        "category": category,
        "seed": int(seed),
        "split": split,
        "params": sampler.params,
    }
    obj = assemble(category, base, movable, provenance)
    log.debug("sampled %s: %d movable parts", object_id(category, seed, split), len(movable))
    return obj

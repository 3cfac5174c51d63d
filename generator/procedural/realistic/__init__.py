"""Realistic procedural objects: the variety, proportions and materials of real ones.

``sample_realistic_object(category, seed, split)`` returns a metric ``ArticulatedObject``
of one of ``REALISTIC_CATEGORIES`` (the seven categories of ``generator.procedural`` and
``"other"``), built with the shared blocks of ``generator.procedural`` (carcasses,
drawers, hinged panels, handles, the assembly) but drawn from what real homes hold:
kitchen base, wall and tall cabinets, dressers, nightstands, sideboards, chests and
filing cabinets; pedestal desks, writing and end tables with drawers, kitchen islands;
ranges, wall and toaster ovens with windowed doors, knobs and hobs; countertop,
over-the-range and drawer microwaves; dishwashers; single, top- and bottom-freezer,
French-door, side-by-side and mini fridges; front and top loading washers and dryers;
and, for "other", shelves, tables, chairs, lamps and the like with no movable part.
Materials are wood with grain, paint, brushed steel, enamel and black glass, tinted per
object (``realistic.looks``). Half of the objects of most categories are mirror images
(left and right swapped: a door hinged on the left becomes one hinged on the right), so
left- and right-hinged doors are balanced (a microwave is mirrored 30 % of the time:
real ones are mostly hinged on the left).

Separate from ``sample_object``: its random streams are keyed by ``"real:<category>"``,
so no output of ``sample_object`` changes, and it does not honour the held-out test
ranges (``HELD_OUT``) of the procedural test split; ``split`` ("train" or "test") only
selects an independent stream of objects. Deterministic for ``(category, seed, split)``.
"""

from __future__ import annotations

import logging
from collections.abc import Callable

import numpy as np

from generator.articulated import ArticulatedObject, Handle, Joint, Primitive
from generator.procedural import CATEGORIES, UnknownCategoryError
from generator.procedural.assembly import PartSpec, assemble
from generator.procedural.realistic import appliances, furniture, other
from generator.procedural.sampling import SPLITS, ParamSampler

__all__ = [
    "MIRROR_P",
    "REALISTIC_CATEGORIES",
    "mirror_specs",
    "realistic_object_id",
    "sample_realistic_object",
]

log = logging.getLogger(__name__)

REALISTIC_CATEGORIES: tuple[str, ...] = (*CATEGORIES, "other")

_BUILDERS: dict[str, Callable[[ParamSampler], tuple[PartSpec, list[PartSpec]]]] = {
    "cabinet": furniture.cabinet,
    "desk": furniture.desk,
    "microwave": appliances.microwave,
    "oven": appliances.oven,
    "dishwasher": appliances.dishwasher,
    "refrigerator": appliances.refrigerator,
    "washing_machine": appliances.washing_machine,
    "other": other.other,
}
#: Probability that an object of a category is built as its mirror image.
MIRROR_P = {c: 0.5 for c in REALISTIC_CATEGORIES} | {"microwave": 0.3}

_M = np.diag([1.0, -1.0, 1.0, 1.0])  # the reflection y -> -y (homogeneous)


def _mirror_primitive(p: Primitive) -> Primitive:
    # M T L with L = the primitive's own y flip: a proper rigid transform, and boxes and
    # cylinders (axis local z) are symmetric under L
    return Primitive(p.kind, p.size.copy(), _M @ p.transform @ _M)


def _mirror_joint(j: Joint) -> Joint:
    axis = _M[:3, :3] @ j.axis
    if j.type == "revolute":  # a reflection reverses the sense of rotation
        axis = -axis
    return Joint(j.type, _M[:3, :3] @ j.origin, axis, j.lower, j.upper, j.parent)


def mirror_specs(specs: list[PartSpec]) -> list[PartSpec]:
    """The part specs reflected through the plane y = 0 (left and right swapped)."""
    out = []
    for spec in specs:
        m = PartSpec(
            semantic=spec.semantic,
            material=spec.material,
            look=spec.look,
            primitives=[_mirror_primitive(p) for p in spec.primitives],
            accent=list(spec.accent),
            joint=None if spec.joint is None else _mirror_joint(spec.joint),
            handle=None
            if spec.handle is None
            else Handle(
                _M[:3, :3] @ spec.handle.position, _M[:3, :3] @ spec.handle.axis, spec.handle.kind
            ),
            order=(spec.order[0], -spec.order[1]),
        )
        out.append(m)
    return out


def _check(category: str, split: str) -> None:
    if category not in _BUILDERS:
        raise UnknownCategoryError(category)
    if split not in SPLITS:
        raise ValueError(f"split must be one of {SPLITS}, got {split!r}")


def realistic_object_id(category: str, seed: int, split: str = "train") -> str:
    """Stable id of a realistic object: ``cabinet_r0000012`` (train), ``cabinet_q0000012``
    (test)."""
    _check(category, split)
    return f"{category}_{'r' if split == 'train' else 'q'}{int(seed):07d}"


def sample_realistic_object(
    category: str, seed: int, split: str = "train", mirror: bool | None = None
) -> ArticulatedObject:
    """The realistic object of ``category`` (one of ``REALISTIC_CATEGORIES``) for ``seed``.

    ``mirror``: None draws it (``MIRROR_P``); True / False forces the mirror image or
    the unmirrored object (the rest of the object is the same). Raises
    UnknownCategoryError for an unknown category and ValueError for a bad split.
    """
    _check(category, split)
    sampler = ParamSampler(f"real:{category}", seed, split)
    base, movable = _BUILDERS[category](sampler)
    drawn = sampler.flag("mirror", MIRROR_P[category])
    mirrored = drawn if mirror is None else bool(mirror)
    sampler.params["mirror"] = mirrored
    if mirrored:
        base, *movable = mirror_specs([base, *movable])
    provenance = {
        "generator": "procedural_realistic",
        "category": category,
        "seed": int(seed),
        "split": split,
        "params": sampler.params,
    }
    obj = assemble(category, base, movable, provenance)
    log.debug(
        "sampled %s: %d movable parts", realistic_object_id(category, seed, split), len(movable)
    )
    return obj

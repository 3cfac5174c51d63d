"""One ArticulatedObject -> the per-object arrays of a dataset shard (docs/dataset.md).

Slots: slot 0 is the base, slots 1.. the other parts in ``obj.parts`` order (movable
parts, and fixed ones should an object have any); mask ids are slot + 1. Geometry
targets live in the normalized object frame: ``x_norm = (x_metric - c) / s`` with ``c``
the centre of the resting object's bounding box and ``s`` its largest extent.
Prismatic joint values and ranges are divided by ``s``; revolute ones stay in radians.
"""

from __future__ import annotations

import logging
from dataclasses import dataclass, field

import numpy as np

from generator.articulated import ArticulatedObject
from generator.data.geometry import occupancy, sample_surface
from generator.data.render import ObjectRenderer, ViewConfig, part_slots, sample_view
from generator.data.shards import JOINT_TYPES, SEMANTICS, pack_occupancy

log = logging.getLogger(__name__)


class ObjectEncodingError(ValueError):
    """An object cannot be stored in the dataset format (too many parts, unknown label...)."""


@dataclass(frozen=True)
class EncodeConfig:
    views: int = 8
    image_size: int = 256
    resolution: int = 32
    max_parts: int = 16
    points_per_part: int = 2048
    view: ViewConfig = field(default_factory=ViewConfig)


def normalization(obj: ArticulatedObject) -> np.ndarray:
    """(4,) [cx, cy, cz, s]: centre of the resting bounding box and its largest extent."""
    meshes = obj.posed_meshes()
    b = np.array([m.bounds for m in meshes.values()])
    lo, hi = b[:, 0].min(0), b[:, 1].max(0)
    s = float(np.max(hi - lo))
    if not s > 0:
        raise ObjectEncodingError("the object has zero size")
    return np.array([*((lo + hi) / 2), s])


def normalized_qpos(
    obj: ArticulatedObject, qpos: np.ndarray, s: float, max_parts: int
) -> np.ndarray:
    """(S,) slot-ordered joint values from ``obj.parts``-ordered ``qpos``; prismatic / s."""
    out = np.zeros(max_parts, np.float32)
    index = {id(p): i for i, p in enumerate(obj.parts)}
    for k, part in enumerate(part_slots(obj)):
        if part.joint is None:
            continue
        q = float(qpos[index[id(part)]])
        out[k] = q / s if part.joint.type == "prismatic" else q
    return out


def encode_object(
    obj: ArticulatedObject,
    object_id: str,
    seed_seq: np.random.SeedSequence,
    config: EncodeConfig | None = None,
) -> dict[str, np.ndarray]:
    """Render ``config.views`` views of ``obj`` and compute its targets.

    Deterministic in ``seed_seq``. Returns the per-object arrays of ``array_spec``.
    """
    config = config or EncodeConfig()
    slots = part_slots(obj)
    S, R, P, V, H = (
        config.max_parts,
        config.resolution,
        config.points_per_part,
        config.views,
        config.image_size,
    )
    if len(slots) > S:
        raise ObjectEncodingError(f"{object_id}: {len(slots)} parts exceed max_parts={S}")
    for p in slots:
        if p.semantic not in SEMANTICS:
            raise ObjectEncodingError(
                f"{object_id}: part {p.name!r} has semantic {p.semantic!r}; known: {SEMANTICS}"
            )
    view_rng, material_rng, surface_rng = (np.random.default_rng(s) for s in seed_seq.spawn(3))
    norm = normalization(obj)
    c, s = norm[:3], float(norm[3])

    rec: dict[str, np.ndarray] = {
        "object_ids": np.array(object_id),
        "category": np.array(obj.category),
        "images": np.zeros((V, H, H, 3), np.uint8),
        "masks": np.zeros((V, H, H), np.uint8),
        "intrinsics": np.zeros((V, 3, 3), np.float32),
        "extrinsics": np.zeros((V, 4, 4), np.float32),
        "view_qpos": np.zeros((V, S), np.float32),
        "part_count": np.array(len(slots), np.int16),
        "occupancy": np.zeros((S, R * R * R // 8), np.uint8),
        "surface_points": np.zeros((S, P, 3), np.float32),
        "surface_colors": np.zeros((S, P, 3), np.uint8),
        "joint_type": np.zeros(S, np.int8),
        "semantic": np.zeros(S, np.int8),
        "joint_origin": np.zeros((S, 3), np.float32),
        "joint_axis": np.zeros((S, 3), np.float32),
        "joint_range": np.zeros((S, 2), np.float32),
        "normalization": norm.astype(np.float32),
    }

    with ObjectRenderer(obj, H, material_rng) as renderer:
        for v in range(V):
            view = sample_view(obj, view_rng, H, config.view)
            out = renderer.render(view)
            rec["images"][v] = out.rgb
            rec["masks"][v] = out.mask
            rec["intrinsics"][v] = out.intrinsics
            rec["extrinsics"][v] = out.extrinsics
            rec["view_qpos"][v] = normalized_qpos(obj, view.qpos, s, S)

    for k, part in enumerate(slots):
        j = part.joint
        rest = part.posed_mesh(j.lower if j is not None else 0.0)
        rest.apply_translation(-c)
        rest.apply_scale(1.0 / s)
        rec["occupancy"][k] = pack_occupancy(occupancy(rest, R))
        points, colors = sample_surface(rest, P, surface_rng)
        rec["surface_points"][k] = points
        rec["surface_colors"][k] = colors
        rec["semantic"][k] = SEMANTICS.index(part.semantic)
        if j is None:
            continue
        rec["joint_type"][k] = JOINT_TYPES.index(j.type)
        rec["joint_origin"][k] = (j.origin - c) / s
        rec["joint_axis"][k] = j.axis
        scale = 1.0 / s if j.type == "prismatic" else 1.0
        rec["joint_range"][k] = (j.lower * scale, j.upper * scale)
    return rec

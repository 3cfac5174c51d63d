"""Part meshes for simulation: watertight geometry at metric scale in the object frame.

Two pure steps, both returning new objects and leaving their inputs untouched:

- :func:`watertight_object` closes every part mesh (:func:`generator.mesh_repair.closing.watertight`:
  kept when already closed, else repaired in place, else voxel-remeshed with colours
  carried over), leaving textured open shells of imported meshes as the artist made them.
- :func:`to_metric` applies the metric scale and moves the object into the frame
  convention (footprint centre of the base at x = y = 0, lowest point at z = 0).
  Joint origins, handles and primitives move with the geometry; prismatic limits
  scale, revolute limits (radians) do not.

Frame convention: right-handed, metres, +z up, the front faces +x (see
``generator/articulated.py``).
"""

from __future__ import annotations

import copy
import logging
from collections.abc import Mapping

import numpy as np

from generator.articulated import ArticulatedObject, Handle, Joint, Part, Primitive

log = logging.getLogger(__name__)

#: Rest bounding-box height (metres) of each category, used when an object has no
#: metric scale (``scale is None``) and no height hint is given.
DEFAULT_HEIGHTS: dict[str, float] = {
    "cabinet": 0.9,
    "desk": 0.75,
    "microwave": 0.3,
    "oven": 0.9,
    "dishwasher": 0.85,
    "refrigerator": 1.8,
    "washing_machine": 0.85,
    "unknown": 1.0,
}

# --------------------------------------------------------------------------- metric scale


def metric_factor(
    obj: ArticulatedObject,
    height: float | None = None,
    default_heights: Mapping[str, float] = DEFAULT_HEIGHTS,
) -> float:
    """Metres per model unit for ``obj``.

    ``obj.scale`` when it is known; otherwise the factor that makes the rest bounding
    box ``height`` metres tall (``height`` defaults to the category's entry of
    ``default_heights``, then to its ``"unknown"`` entry, then to 1.0).
    """
    if obj.scale is not None:
        if height is not None:
            log.info("object has metric scale %g; ignoring the height hint %g", obj.scale, height)
        return float(obj.scale)
    if height is None:
        height = default_heights.get(obj.category, default_heights.get("unknown", 1.0))
    if not (height > 0 and np.isfinite(height)):
        raise ValueError(f"height must be a positive number of metres, got {height}")
    h = float(np.ptp(obj.bounds()[:, 2]))
    if h <= 0:
        raise ValueError("the object has zero height; cannot infer a metric scale")
    return float(height) / h


def similarity(scale: float, offset: np.ndarray) -> np.ndarray:
    """4x4 matrix of ``p -> scale * p + offset`` (offset shape (3,))."""
    T = np.diag([scale, scale, scale, 1.0])
    T[:3, 3] = offset
    return T


def frame_offset(obj: ArticulatedObject, scale: float) -> np.ndarray:
    """(3,) translation that puts ``scale``-scaled ``obj`` into the frame convention.

    x, y: centre of the base part's footprint; z: the lowest point of the whole
    object at rest lands on the floor.
    """
    base_b = obj.base.mesh.bounds * scale
    all_b = obj.bounds() * scale
    centre = base_b.mean(axis=0)
    return np.array([-centre[0], -centre[1], -all_b[0, 2]])


def _transform_primitive(prim: Primitive, scale: float, T: np.ndarray) -> Primitive:
    M = prim.transform.copy()
    M[:3, 3] = (T @ np.append(M[:3, 3], 1.0))[:3]
    return Primitive(kind=prim.kind, size=prim.size * scale, transform=M)


def transform_object(obj: ArticulatedObject, scale: float, offset: np.ndarray) -> ArticulatedObject:
    """Copy of ``obj`` under ``p -> scale * p + offset`` with everything moved along.

    Meshes, joint origins, handle positions and primitive placements transform as
    points; axes do not change; primitive sizes and prismatic limits scale; revolute
    limits stay (radians). The result has ``scale = 1.0`` when ``obj.scale`` was None,
    otherwise ``obj.scale / scale`` (i.e. 1.0 for a metric factor from
    :func:`metric_factor`).
    """
    T = similarity(scale, np.asarray(offset, dtype=float))
    parts = []
    for p in obj.parts:
        m = p.mesh.copy()
        m.apply_transform(T)
        joint = None
        if p.joint is not None:
            j = p.joint
            f = scale if j.type == "prismatic" else 1.0
            joint = Joint(
                type=j.type,
                origin=(T @ np.append(j.origin, 1.0))[:3],
                axis=j.axis.copy(),
                lower=j.lower * f,
                upper=j.upper * f,
                parent=j.parent,
            )
        handle = None
        if p.handle is not None:
            handle = Handle(
                position=(T @ np.append(p.handle.position, 1.0))[:3],
                axis=p.handle.axis.copy(),
                kind=p.handle.kind,
            )
        parts.append(
            Part(
                name=p.name,
                semantic=p.semantic,
                mesh=m,
                joint=joint,
                primitives=[_transform_primitive(q, scale, T) for q in p.primitives],
                handle=handle,
                material=p.material,
            )
        )
    new_scale = 1.0 if obj.scale is None else obj.scale / scale
    return ArticulatedObject(
        parts=parts,
        category=obj.category,
        scale=new_scale,
        provenance=copy.deepcopy(obj.provenance),
    )


def to_metric(
    obj: ArticulatedObject,
    height: float | None = None,
    default_heights: Mapping[str, float] = DEFAULT_HEIGHTS,
) -> ArticulatedObject:
    """``obj`` in metres and in the frame convention (``scale == 1.0`` on the result).

    See :func:`metric_factor` for how the factor is chosen and :func:`frame_offset`
    for the placement. The factor applied is recorded in
    ``provenance["metric_scale"]``.
    """
    s = metric_factor(obj, height, default_heights)
    out = transform_object(obj, s, frame_offset(obj, s))
    out.scale = 1.0
    out.provenance["metric_scale"] = s
    return out

"""Primitive solids (boxes, cylinders) and their exact watertight union.

All coordinates are metres in the object frame (+z up, front faces +x). A part is
a list of ``Primitive``; its mesh is the manifold3d boolean union of the
primitives' meshes (``Primitive.to_mesh``, 16-sided cylinders), so the collision
stage can use the primitives themselves as exact convex pieces.
"""

from __future__ import annotations

from collections.abc import Sequence

import manifold3d
import numpy as np
import trimesh

from generator.articulated import Primitive

# Overlap (m) given to primitives of one part that meet, so the union is one clean solid.
EPS = 1e-3
CYLINDER_SECTIONS = 16

_AXIS_ROTATIONS = {
    # columns: images of the local x, y, z axes; local z is the cylinder axis
    0: np.array([[0.0, 0.0, 1.0], [0.0, 1.0, 0.0], [-1.0, 0.0, 0.0]]),
    1: np.array([[1.0, 0.0, 0.0], [0.0, 0.0, 1.0], [0.0, -1.0, 0.0]]),
    2: np.eye(3),
}


def box(lo: Sequence[float], hi: Sequence[float]) -> Primitive:
    """Axis-aligned box between corners ``lo`` and ``hi`` (each (3,), metres)."""
    lo_, hi_ = np.asarray(lo, dtype=float), np.asarray(hi, dtype=float)
    size = hi_ - lo_
    if np.any(size <= 0):
        raise ValueError(f"box needs lo < hi on every axis, got {lo_.tolist()} {hi_.tolist()}")
    transform = np.eye(4)
    transform[:3, 3] = (lo_ + hi_) / 2
    return Primitive("box", size, transform)


def cylinder(center: Sequence[float], radius: float, length: float, axis: int) -> Primitive:
    """Cylinder of ``radius`` and ``length`` (m) centred at ``center`` (3,), along object axis
    ``axis`` (0 = x, 1 = y, 2 = z)."""
    if radius <= 0 or length <= 0:
        raise ValueError(f"cylinder needs positive radius and length, got {radius}, {length}")
    transform = np.eye(4)
    transform[:3, :3] = _AXIS_ROTATIONS[axis]
    transform[:3, 3] = np.asarray(center, dtype=float)
    return Primitive("cylinder", [radius, length], transform)


def _to_manifold(mesh: trimesh.Trimesh) -> manifold3d.Manifold:
    return manifold3d.Manifold(
        mesh=manifold3d.Mesh(
            vert_properties=np.asarray(mesh.vertices, dtype=np.float32),
            tri_verts=np.asarray(mesh.faces, dtype=np.uint32),
        )
    )


def union_mesh(primitives: Sequence[Primitive]) -> trimesh.Trimesh:
    """The watertight boolean union of ``primitives`` (float32-exact vertices)."""
    if not primitives:
        raise ValueError("a part needs at least one primitive")
    solids = [_to_manifold(p.to_mesh(sections=CYLINDER_SECTIONS)) for p in primitives]
    result = manifold3d.Manifold.batch_boolean(solids, manifold3d.OpType.Add)
    out = result.to_mesh()
    mesh = trimesh.Trimesh(
        vertices=np.asarray(out.vert_properties[:, :3], dtype=np.float32).astype(np.float64),
        faces=np.asarray(out.tri_verts, dtype=np.int64),
        process=False,
    )
    if not mesh.is_watertight:
        raise RuntimeError("union of primitives is not watertight")
    return mesh


def inside_primitive(points: np.ndarray, prim: Primitive, tol: float = 1e-5) -> np.ndarray:
    """(N,) bool: which of ``points`` (N, 3) lie inside or on ``prim`` (within ``tol`` m)."""
    rot, centre = prim.transform[:3, :3], prim.transform[:3, 3]
    local = (np.asarray(points, dtype=float) - centre) @ rot
    if prim.kind == "box":
        return np.all(np.abs(local) <= prim.size / 2 + tol, axis=1)
    radius, height = prim.size
    return (np.hypot(local[:, 0], local[:, 1]) <= radius + tol) & (
        np.abs(local[:, 2]) <= height / 2 + tol
    )

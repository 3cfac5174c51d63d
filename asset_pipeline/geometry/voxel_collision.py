"""Articulation-aware collision pieces: boxes cut from voxels, clear of every part's sweep.

Artist-made meshes (PartNet-Mobility, CAD exports, other generators' outputs) are open
shells with internal faces and dozens of loose pieces. Decomposing each part alone
(CoACD) gives hulls that fill the cavities the drawers and doors sit in. Here the
whole object is decomposed together, in one voxel grid of the object frame:

1. Occupancy. Each part's surface is sampled densely (deterministic barycentric
   lattices, spacing at most half a voxel) and splatted into the grid; cavities the
   part's own voxels enclose are filled (a closed door is solid, an open carcass stays
   open: background connects through voxel faces only).
2. Sweeps. Each movable part's occupancy (surface samples and filled voxel centres)
   is moved through its joint range in steps of at most half a voxel at its farthest
   point and splatted again: the space the part occupies at some joint value.
3. Carving. The base loses every voxel within ``clearance`` voxels of any movable
   part's sweep (drawer slots, door swings, the parts' own rest volumes stay free);
   two movable parts whose rest volumes touch give the overlap to the larger one.
4. Boxes. Each part's remaining voxels are run-length merged into boxes (x runs, then
   y, then z), neighbouring boxes are merged greedily while the merged box stays
   filled to ``1 - merge_slack``, gains at most a ``merge_depth`` layer of empty space
   over its largest face and stays off every carved voxel (summed-volume tables make
   each test O(1)); while more than ``max_pieces`` remain, the pair whose merge adds the
   least empty volume goes first (a handle standing off a door keeps its own box
   unless nothing cheaper is left). Finally each box is tightened to the samples and
   filled voxels it holds, so an axis-aligned panel's piece is the panel itself, not
   its voxels.

The pieces are boxes in the object frame (8 vertices each), never inside a voxel
another part sweeps through; they cover the part's surface samples (a sample can only
be lost where it lies in another part's swept space). Everything is numpy: no
external process, deterministic for the same meshes, joints and parameters; results
are cached on disk by a hash of those. Units: metres.
"""

from __future__ import annotations

import hashlib
import io
import json
import logging
import math
import os
import time
from collections.abc import Callable
from dataclasses import asdict, dataclass, field
from pathlib import Path

import numpy as np
import trimesh
from scipy import ndimage

from asset_pipeline.geometry.sweeps import HullSet, swept_hulls
from generator.articulated import ArticulatedObject, Part, Primitive
from generator.atomic_files import atomic_write_bytes

log = logging.getLogger(__name__)

CACHE_VERSION = 10
#: Past the time-out the pitch doubles; at this multiple it runs to the end whatever
#: it takes (a coarse but valid, sweep-free decomposition).
FALLBACK_SCALE = 8.0


@dataclass(frozen=True)
class VoxelCollisionParams:
    """How fine and how many: all part of the cache key."""

    #: Voxels along the object's largest rest extent (the pitch is clamped below).
    resolution: int = 128
    min_pitch: float = 0.004
    max_pitch: float = 0.010
    #: Voxels kept free around every sweep in the first, voxel cut.
    clearance: int = 1
    #: Distance (m) kept between the base's boxes and the exact sweeps.
    margin: float = 0.0005
    #: A merge may add at most this fraction of empty volume to the merged box...
    merge_slack: float = 0.12
    #: ...and at most a layer this thick (m) over the merged box's largest face: a
    #: knob does not stretch the drawer's bottom panel across the whole front.
    merge_depth: float = 0.006
    #: Pieces per part at most (past the slack, the pair adding the least empty volume
    #: merges first until this many remain).
    max_pieces: int = 48
    #: Thinnest piece (m) after tightening.
    min_thickness: float = 0.002
    #: Seconds for the whole object; past it the pitch doubles and the work restarts.
    timeout: float = 120.0


DEFAULT_PARAMS = VoxelCollisionParams()


@dataclass
class VoxelCollisionResult:
    """Pieces per part (object frame) and what it took."""

    pieces: dict[str, list[trimesh.Trimesh]]
    pitch: float
    seconds: float
    carved_voxels: dict[str, int] = field(default_factory=dict)
    cached: bool = False


# --------------------------------------------------------------------------- sampling


def surface_points(mesh: trimesh.Trimesh, spacing: float) -> np.ndarray:
    """(N, 3) points on ``mesh``'s triangles, every surface point within ``spacing`` of one.

    Each triangle is covered by rows parallel to its longest edge, at most ``spacing``
    apart, each row sampled at most ``spacing`` apart (its ends included), so the count
    grows with the area, not with the longest edge squared (slivers stay cheap).
    Deterministic (no random sampling).
    """
    tri = np.asarray(mesh.triangles, dtype=np.float64)
    if len(tri) == 0:
        return np.zeros((0, 3))
    # order each triangle's vertices so that (a, b) is its longest edge and c the apex
    lengths = np.linalg.norm(tri[:, [1, 2, 0]] - tri, axis=2)  # edges 01, 12, 20
    k = np.argmax(lengths, axis=1)
    a = tri[np.arange(len(tri)), k]
    b = tri[np.arange(len(tri)), (k + 1) % 3]
    c = tri[np.arange(len(tri)), (k + 2) % 3]
    long = lengths[np.arange(len(tri)), k]
    area2 = np.linalg.norm(np.cross(b - a, c - a), axis=1)
    height = np.where(long > 0, area2 / np.maximum(long, 1e-300), 0.0)
    rows = np.maximum(1, np.ceil(height / spacing)).astype(np.int64)  # row gaps per triangle
    # one entry per row: its triangle and t = fraction of the way from edge ab to c
    tri_of_row = np.repeat(np.arange(len(tri)), rows + 1)
    first = np.repeat(np.cumsum(rows + 1) - (rows + 1), rows + 1)
    t = (np.arange(len(tri_of_row)) - first) / rows[tri_of_row]
    p0 = a[tri_of_row] + t[:, None] * (c[tri_of_row] - a[tri_of_row])
    p1 = b[tri_of_row] + t[:, None] * (c[tri_of_row] - b[tri_of_row])
    per_row = np.ceil(long[tri_of_row] * (1.0 - t) / spacing).astype(np.int64) + 1
    row_of_point = np.repeat(np.arange(len(t)), per_row)
    start = np.repeat(np.cumsum(per_row) - per_row, per_row)
    u = (np.arange(len(row_of_point)) - start) / np.maximum(per_row[row_of_point] - 1, 1)
    return p0[row_of_point] + u[:, None] * (p1[row_of_point] - p0[row_of_point])


# --------------------------------------------------------------------------- the grid


@dataclass(frozen=True)
class Grid:
    """A voxel grid of the object frame: ``origin`` (3,) of cell (0, 0, 0)'s low corner,
    ``pitch`` (m), ``shape`` (3,) cells."""

    origin: np.ndarray
    pitch: float
    shape: tuple[int, int, int]

    def index(self, points: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """(N, 3) int cell indices of ``points`` and a (N,) mask of those inside the grid."""
        idx = np.floor((points - self.origin) / self.pitch).astype(np.int64)
        inside = np.all((idx >= 0) & (idx < np.array(self.shape)), axis=1)
        return idx, inside

    def splat(self, points: np.ndarray, into: np.ndarray | None = None) -> np.ndarray:
        occ = np.zeros(self.shape, bool) if into is None else into
        idx, inside = self.index(points)
        idx = idx[inside]
        occ[idx[:, 0], idx[:, 1], idx[:, 2]] = True
        return occ

    def centres(self, occ: np.ndarray) -> np.ndarray:
        return (np.argwhere(occ) + 0.5) * self.pitch + self.origin


def make_grid(obj: ArticulatedObject, params: VoxelCollisionParams, scale: float = 1.0) -> Grid:
    lo, hi = obj.bounds()
    pitch = float(np.clip(np.max(hi - lo) / params.resolution, params.min_pitch, params.max_pitch))
    pitch *= scale
    margin = (params.clearance + 2) * pitch
    origin = lo - margin
    shape = tuple(int(n) for n in np.ceil((hi + margin - origin) / pitch))
    return Grid(origin=origin, pitch=pitch, shape=shape)  # type: ignore[arg-type]


def fill_enclosed(occ: np.ndarray) -> np.ndarray:
    """``occ`` with every cavity it encloses filled (background through faces only)."""
    return ndimage.binary_fill_holes(occ)


# --------------------------------------------------------------------------- sweeps


def _joint_steps(part: Part, points: np.ndarray, pitch: float) -> np.ndarray:
    """Joint values from lower to upper so that no point moves more than a pitch a step."""
    j = part.joint
    assert j is not None
    if j.type == "prismatic":
        reach = abs(j.upper - j.lower)
    else:
        r = np.linalg.norm(np.cross(points - j.origin, j.axis), axis=1).max(initial=0.0)
        reach = abs(j.upper - j.lower) * float(r)
    n = max(1, math.ceil(reach / pitch))
    return np.linspace(j.lower, j.upper, n + 1)


def swept_occupancy(part: Part, occ: np.ndarray, grid: Grid) -> np.ndarray:
    """Cells the part, whose rest occupancy is ``occ``, passes through over its range.

    A cell inside the part at some joint value is inside it at rest, or on its surface
    at some joint value: so the rest occupancy and the moved centres of its boundary
    cells (steps of at most a pitch; the caller's dilation by at least one cell closes
    the gaps between steps) cover the sweep.
    """
    boundary = occ & ~ndimage.binary_erosion(occ)
    points = grid.centres(boundary)
    swept = occ.copy()
    for q in _joint_steps(part, points, grid.pitch):
        T = part.joint.transform(float(q))  # type: ignore[union-attr]
        grid.splat(points @ T[:3, :3].T + T[:3, 3], into=swept)
    return swept


# --------------------------------------------------------------------------- boxes


def _runs(occ: np.ndarray) -> list[tuple[int, int, int, int, int, int]]:
    """Boxes [x0, x1) x [y0, y1) x [z0, z1) (cell indices) covering ``occ`` exactly:
    runs along x merged across y, then across z."""
    nx, ny, nz = occ.shape
    pad = np.zeros((nx + 2, ny, nz), bool)
    pad[1:-1] = occ
    d = np.diff(pad.astype(np.int8), axis=0)  # (nx + 1, ny, nz)
    starts = np.argwhere(d == 1)  # (x0, y, z)
    ends = np.argwhere(d == -1)  # (x1, y, z)
    order_s = np.lexsort((starts[:, 0], starts[:, 1], starts[:, 2]))
    order_e = np.lexsort((ends[:, 0], ends[:, 1], ends[:, 2]))
    starts, ends = starts[order_s], ends[order_e]
    # rectangles in (x, y) per z: extend a run to y + 1 when the same run exists there
    rects: list[list[int]] = []  # x0, x1, y0, y1, z
    open_: dict[tuple[int, int, int], int] = {}
    for (x0, y, z), (x1, _, _) in zip(starts.tolist(), ends.tolist(), strict=True):
        key = (z, x0, x1)
        k = open_.get(key)
        if k is not None and rects[k][3] == y:
            rects[k][3] = y + 1
        else:
            open_[key] = len(rects)
            rects.append([x0, x1, y, y + 1, z])
    # boxes: extend a rectangle to z + 1 when the same rectangle exists there
    rects.sort(key=lambda r: (r[4], r[0], r[2]))
    boxes: list[list[int]] = []
    open3: dict[tuple[int, int, int, int], int] = {}
    for x0, x1, y0, y1, z in rects:
        key = (x0, x1, y0, y1)
        k = open3.get(key)
        if k is not None and boxes[k][5] == z:
            boxes[k][5] = z + 1
        else:
            open3[key] = len(boxes)
            boxes.append([x0, x1, y0, y1, z, z + 1])
    return [tuple(b) for b in boxes]  # type: ignore[misc]


class _Volume:
    """Summed-volume table of a bool grid: the count of True cells in any box, in O(1)."""

    def __init__(self, occ: np.ndarray) -> None:
        s = np.zeros(tuple(n + 1 for n in occ.shape), np.int64)
        s[1:, 1:, 1:] = occ.astype(np.int64).cumsum(0).cumsum(1).cumsum(2)
        self.s = s

    def count(self, b: np.ndarray) -> np.ndarray:
        """True cells in boxes ``b`` (M, 6) = [x0, x1, y0, y1, z0, z1]."""
        s = self.s
        x0, x1, y0, y1, z0, z1 = (b[:, i] for i in range(6))
        return (
            s[x1, y1, z1] - s[x0, y1, z1] - s[x1, y0, z1] - s[x1, y1, z0]
            + s[x0, y0, z1] + s[x0, y1, z0] + s[x1, y0, z0] - s[x0, y0, z0]
        )  # fmt: skip


def merge_boxes(
    boxes: np.ndarray,
    filled: _Volume,
    blocked: _Volume,
    slack: float,
    max_boxes: int,
    depth: float = math.inf,
) -> np.ndarray:
    """Merge neighbouring boxes (M, 6) of cells; see the module docstring.

    First greedily, smallest boxes first: two touching boxes become their bounding box
    when it holds no blocked cell, its filled cells are at least ``1 - slack`` of its
    volume and its empty cells at most a layer ``depth`` cells thick over its largest
    face. While more than ``max_boxes`` remain, the pair whose bounding box adds the
    fewest empty cells (and no blocked one) is merged, one pair at a time
    (:func:`merge_cheapest`): a handle standing off a door stays a box of its own while
    any cheaper merge is left.
    """
    arr = np.array(boxes, dtype=np.int64).reshape(-1, 6)
    alive = np.ones(len(arr), bool)
    while True:
        merged_any = False
        vol = np.prod(arr[:, 1::2] - arr[:, 0::2], axis=1)
        for i in np.argsort(vol, kind="stable"):
            if not alive[i]:
                continue
            b = arr[i]
            touch = alive & np.all((arr[:, 0::2] <= b[1::2]) & (arr[:, 1::2] >= b[0::2]), axis=1)
            touch[i] = False
            cand = np.nonzero(touch)[0]
            if len(cand) == 0:
                continue
            u = np.empty((len(cand), 6), np.int64)
            u[:, 0::2] = np.minimum(arr[cand, 0::2], b[0::2])
            u[:, 1::2] = np.maximum(arr[cand, 1::2], b[1::2])
            ext = u[:, 1::2] - u[:, 0::2]
            uvol = np.prod(ext, axis=1)
            empty = uvol - filled.count(u)
            face = uvol / ext.min(axis=1)
            ok = (empty <= slack * uvol) & (empty <= depth * face) & (blocked.count(u) == 0)
            if not ok.any():
                continue
            k = int(np.argmin(np.where(ok, uvol, np.iinfo(np.int64).max)))
            arr[i] = u[k]
            alive[cand[k]] = False
            arr[cand[k]] = 0
            merged_any = True
        arr, alive = arr[alive], alive[alive]
        if not merged_any:
            break
    if len(arr) <= max_boxes:
        return arr

    def cost(a: np.ndarray, i: int, others: np.ndarray) -> np.ndarray:
        b = a[i]
        u = np.empty((len(others), 6), np.int64)
        u[:, 0::2] = np.minimum(a[others, 0::2], b[0::2])
        u[:, 1::2] = np.maximum(a[others, 1::2], b[1::2])
        touch = np.all((a[others, 0::2] <= b[1::2]) & (a[others, 1::2] >= b[0::2]), axis=1)
        empty = np.prod(u[:, 1::2] - u[:, 0::2], axis=1) - filled.count(u)
        return np.where(touch & (blocked.count(u) == 0), empty.astype(np.float64), np.inf)

    def union(a: np.ndarray, b: np.ndarray) -> np.ndarray:
        u = np.empty(6, np.int64)
        u[0::2] = np.minimum(a[0::2], b[0::2])
        u[1::2] = np.maximum(a[1::2], b[1::2])
        return u

    return merge_cheapest(arr, max_boxes, cost, union)


def merge_cheapest(
    boxes: np.ndarray,
    max_boxes: int,
    cost: Callable[[np.ndarray, int, np.ndarray], np.ndarray],
    union: Callable[[np.ndarray, np.ndarray], np.ndarray],
    allowed: Callable[[np.ndarray], bool] | None = None,
) -> np.ndarray:
    """Merge the cheapest pair of ``boxes`` into their ``union`` until ``max_boxes``
    remain or no pair may merge; returns the boxes left.

    ``cost(boxes, i, others)``: the cost of merging box ``i`` with each of ``others``
    (inf: never). ``allowed(union)``: a costlier test made only on the cheapest pair (a
    pair it refuses is not tried again). A cost matrix with per-row minima is updated
    for the merged box only: O(n) per merge after an O(n^2) start.
    """
    a = np.array(boxes)
    n = len(a)
    C = np.full((n, n), np.inf)
    for i in range(n - 1):
        C[i, i + 1 :] = cost(a, i, np.arange(i + 1, n))
    alive = np.ones(n, bool)
    row_arg = C.argmin(axis=1) if n else np.zeros(0, np.int64)
    row_min = C[np.arange(n), row_arg] if n else np.zeros(0)
    count = n
    while count > max_boxes:
        i = int(np.argmin(row_min))
        if not np.isfinite(row_min[i]):
            break
        j = int(row_arg[i])
        u = union(a[i], a[j])
        if allowed is not None and not allowed(u):
            C[i, j] = np.inf
            row_arg[i] = int(np.argmin(C[i]))
            row_min[i] = C[i, row_arg[i]]
            continue
        a[i] = u
        alive[j] = False
        count -= 1
        C[j, :] = np.inf
        C[:, j] = np.inf
        row_min[j] = np.inf
        others = np.nonzero(alive)[0]
        others = others[others != i]
        c = cost(a, i, others) if len(others) else np.zeros(0)
        C[i, :] = np.inf
        C[:, i] = np.inf
        before = others < i
        C[others[before], i] = c[before]
        C[i, others[~before]] = c[~before]
        row_arg[i] = int(np.argmin(C[i]))
        row_min[i] = C[i, row_arg[i]]
        # rows whose minimum was at i or j: searched again; the others may drop to C[r, i]
        stale = np.nonzero(alive & ((row_arg == i) | (row_arg == j)))[0]
        stale = stale[stale != i]
        if len(stale):
            row_arg[stale] = C[stale].argmin(axis=1)
            row_min[stale] = C[stale, row_arg[stale]]
        rows = others[before]
        lower = C[rows, i] < row_min[rows]
        row_arg[rows[lower]] = i
        row_min[rows[lower]] = C[rows[lower], i]
    return a[alive]


class CellBounds:
    """Per cell of a grid, the bounds (3,) of the points that fall in it (+inf / -inf
    where none do): boxes of cells are tightened to their points by a reduction."""

    def __init__(self, grid: Grid, points: np.ndarray) -> None:
        idx, inside = grid.index(points)
        idx, points = idx[inside], points[inside]
        flat = np.ravel_multi_index(idx.T, grid.shape)
        n = int(np.prod(grid.shape))
        self.lo = np.full((n, 3), np.inf, np.float32)
        self.hi = np.full((n, 3), -np.inf, np.float32)
        for a in range(3):
            np.minimum.at(self.lo[:, a], flat, points[:, a].astype(np.float32))
            np.maximum.at(self.hi[:, a], flat, points[:, a].astype(np.float32))
        self.lo = self.lo.reshape(*grid.shape, 3)
        self.hi = self.hi.reshape(*grid.shape, 3)

    def of(self, box: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Bounds of the points in ``box`` [x0, x1, y0, y1, z0, z1] (inf when none)."""
        sl = (slice(box[0], box[1]), slice(box[2], box[3]), slice(box[4], box[5]))
        lo = self.lo[sl].reshape(-1, 3).min(axis=0)
        hi = self.hi[sl].reshape(-1, 3).max(axis=0)
        return lo.astype(np.float64), hi.astype(np.float64)


def tighten(box: np.ndarray, grid: Grid, cells: CellBounds, min_thickness: float) -> np.ndarray:
    """(2, 3) metric bounds of ``box`` (cell indices) shrunk to the points inside it
    (surface samples and filled-cell corners), at least ``min_thickness`` thick."""
    lo = grid.origin + box[0::2] * grid.pitch
    hi = grid.origin + box[1::2] * grid.pitch
    plo, phi = cells.of(box)
    if np.isfinite(plo).all():
        lo, hi = np.maximum(lo, plo), np.minimum(hi, phi)
    short = (hi - lo) < min_thickness
    mid = 0.5 * (lo + hi)
    lo = np.where(short, mid - 0.5 * min_thickness, lo)
    hi = np.where(short, mid + 0.5 * min_thickness, hi)
    return np.stack([lo, hi])


def box_mesh(bounds: np.ndarray) -> trimesh.Trimesh:
    lo, hi = bounds
    return trimesh.creation.box(
        extents=hi - lo, transform=trimesh.transformations.translation_matrix(0.5 * (lo + hi))
    )


def box_primitive(bounds: np.ndarray) -> Primitive:
    lo, hi = bounds
    return Primitive("box", hi - lo, trimesh.transformations.translation_matrix(0.5 * (lo + hi)))


# --------------------------------------------------------------------------- exact refinement


class PointIndex:
    """Points bucketed by grid cell, for the points inside any box in time ~ its cells."""

    def __init__(self, grid: Grid, points: np.ndarray) -> None:
        idx, inside = grid.index(points)
        flat = np.ravel_multi_index(idx[inside].T, grid.shape)
        order = np.argsort(flat, kind="stable")
        self.grid = grid
        self.points = points[inside][order]
        self.flat = flat[order]

    def inside(self, lo: np.ndarray, hi: np.ndarray) -> np.ndarray:
        """(M, 3) points within [lo, hi] (metres)."""
        g = self.grid
        a = np.clip(np.floor((lo - g.origin) / g.pitch).astype(int), 0, np.array(g.shape) - 1)
        b = np.clip(np.floor((hi - g.origin) / g.pitch).astype(int), 0, np.array(g.shape) - 1)
        cells = np.stack(
            np.meshgrid(*(np.arange(a[k], b[k] + 1) for k in range(3)), indexing="ij"), -1
        ).reshape(-1, 3)
        flat = np.ravel_multi_index(cells.T, g.shape)
        start = np.searchsorted(self.flat, flat, side="left")
        stop = np.searchsorted(self.flat, flat, side="right")
        counts = stop - start
        total = int(counts.sum())
        if total == 0:
            return np.zeros((0, 3))
        # indices start[i] .. stop[i] - 1 of every cell, without a Python loop
        offsets = np.repeat(start - np.cumsum(counts) + counts, counts)
        take = offsets + np.arange(total)
        p = self.points[take]
        return p[np.all((p >= lo) & (p <= hi), axis=1)]


def _tight(lo: np.ndarray, hi: np.ndarray, index: PointIndex, min_thickness: float):
    """[lo, hi] shrunk to the points in it (None when it holds none), at least
    ``min_thickness`` thick."""
    p = index.inside(lo, hi)
    if len(p) == 0:
        return None
    lo, hi = p.min(axis=0), p.max(axis=0)
    mid, short = 0.5 * (lo + hi), (hi - lo) < min_thickness
    return (
        np.where(short, mid - 0.5 * min_thickness, lo),
        np.where(short, mid + 0.5 * min_thickness, hi),
    )


def shrink_clear(
    boxes: np.ndarray, forbidden: HullSet, margin: float, max_loss: float = 0.5, steps: int = 10
) -> list[np.ndarray | None]:
    """Per box of ``boxes`` (M, 2, 3): the box with one side moved in just enough to
    clear ``forbidden`` (to within ``max_loss`` of its extent / 2**steps), the side losing
    the least volume; None when no single side clears it within ``max_loss``. The six
    sides of all M boxes are bisected together, one ``forbidden.intersects`` call per
    bisection step."""
    boxes = np.asarray(boxes, dtype=np.float64)
    m = len(boxes)
    if m == 0:
        return []
    ext = boxes[:, 1] - boxes[:, 0]  # (M, 3)
    # the six sides in the order k = 0..2, side = 0, 1 (ties keep the first)
    ks = np.repeat(np.arange(3), 2)
    sides = np.tile(np.arange(2), 3)
    sign = np.where(sides == 0, 1.0, -1.0)

    def moved(d: np.ndarray) -> np.ndarray:
        """(M, 6, 2, 3): every box with side (k, side) moved in by ``d`` (M, 6)."""
        out = np.repeat(boxes[:, None], 6, axis=1)
        out[:, np.arange(6), sides, ks] += sign * d
        return out

    def hits(cand: np.ndarray, rows: np.ndarray) -> np.ndarray:
        flat = cand.reshape(-1, 2, 3)[rows]
        return forbidden.intersects(flat[:, 0], flat[:, 1], margin)

    hi_d = max_loss * ext[:, ks]  # (M, 6)
    lo_d = np.zeros_like(hi_d)
    free = ~hits(moved(hi_d), np.arange(6 * m)).reshape(m, 6)
    rows = np.flatnonzero(free.ravel())
    for _ in range(steps):
        if len(rows) == 0:
            break
        mid = 0.5 * (lo_d + hi_d)
        hit = np.zeros((m, 6), bool)
        hit.ravel()[rows] = hits(moved(mid), rows)
        lo_d = np.where(free & hit, mid, lo_d)
        hi_d = np.where(free & ~hit, mid, hi_d)
    loss = np.where(free, hi_d / np.maximum(ext[:, ks], 1e-12), np.inf)
    best = np.argmin(loss, axis=1)
    final = moved(hi_d)
    return [final[i, best[i]] if np.isfinite(loss[i, best[i]]) else None for i in range(m)]


def refine_boxes(
    boxes: list[np.ndarray],
    index: PointIndex,
    forbidden: HullSet,
    margin: float,
    min_size: float,
) -> list[np.ndarray]:
    """Boxes ((2, 3) bounds) kept off ``forbidden`` (with ``margin``). A box that meets it
    loses a slab from one side when that clears it for at most half its extent (the
    side that costs the least volume: two drawers stacked face to face part by a
    margin); else it is halved across its longest side, each half tightened to its
    points, until the halves are clear or no longer than ``min_size`` (then dropped)."""
    out: list[np.ndarray] = []
    todo = [np.asarray(b, dtype=np.float64) for b in boxes]
    while todo:
        arr = np.array(todo)
        hit = forbidden.intersects(arr[:, 0], arr[:, 1], margin)
        out += [b for b, h in zip(todo, hit, strict=True) if not h]
        todo = []
        hit_boxes = arr[hit]
        for b, trimmed in zip(hit_boxes, shrink_clear(hit_boxes, forbidden, margin), strict=True):
            if trimmed is not None:
                t = _tight(trimmed[0], trimmed[1], index, 0.0)
                if t is not None:
                    out.append(np.stack(t))
                continue
            ext = b[1] - b[0]
            k = int(np.argmax(ext))
            if ext[k] <= min_size:
                continue
            mid = 0.5 * (b[0][k] + b[1][k])
            for lo_k, hi_k in ((b[0][k], mid), (mid, b[1][k])):
                lo, hi = b[0].copy(), b[1].copy()
                lo[k], hi[k] = lo_k, hi_k
                t = _tight(lo, hi, index, 0.0)
                if t is not None:
                    todo.append(np.stack(t))
    return out


def merge_exact(
    boxes: list[np.ndarray],
    index: PointIndex,
    forbidden: HullSet,
    margin: float,
    slack: float,
    max_boxes: int,
    min_thickness: float,
    pitch: float,
    within: np.ndarray | None = None,
    depth: float = math.inf,
) -> list[np.ndarray]:
    """Merge neighbouring boxes ((2, 3) bounds) into their bounding box while it stays
    off ``forbidden``, within ``1 + slack`` of the two volumes and adds at most a layer
    ``depth`` (m) thick over its largest face; then, while more than
    ``max_boxes`` remain, the pair whose bounding box adds the least volume
    (:func:`merge_cheapest`). The results are tightened to their points. Volumes count
    every side as at least ``pitch`` long, so thin boxes a fraction of a voxel apart
    merge as voxels would. ``within`` (K, 2, 3): a merged box must lie in one of these
    boxes, and thin boxes grow only inside them (a part never outgrows the envelope its
    sweep was computed from)."""
    arr = np.array(boxes, dtype=np.float64).reshape(-1, 2, 3)
    alive = np.ones(len(arr), bool)
    touch_gap = max(2 * min_thickness, pitch)

    def volume(lo: np.ndarray, hi: np.ndarray) -> np.ndarray:
        return np.prod(np.maximum(hi - lo, pitch), axis=-1)

    while True:
        merged_any = False
        vol = volume(arr[:, 0], arr[:, 1])
        for i in np.argsort(vol, kind="stable"):
            if not alive[i]:
                continue
            lo, hi = arr[i]
            near = alive & np.all(
                (arr[:, 0] <= hi + touch_gap) & (arr[:, 1] >= lo - touch_gap), axis=1
            )
            near[i] = False
            cand = np.nonzero(near)[0]
            if len(cand) == 0:
                continue
            ulo = np.minimum(arr[cand, 0], lo)
            uhi = np.maximum(arr[cand, 1], hi)
            uvol = volume(ulo, uhi)
            added = uvol - vol[i] - vol[cand]
            face = uvol / np.maximum(uhi - ulo, pitch).min(axis=1)
            ok = (added <= slack * (vol[i] + vol[cand])) & (added <= depth * face)
            if within is not None:
                ok &= inside_any(ulo, uhi, within)
            if not ok.any():
                continue
            ok[ok] = ~forbidden.intersects(ulo[ok], uhi[ok], margin)
            if not ok.any():
                continue
            k = int(np.argmin(np.where(ok, uvol, np.inf)))
            arr[i] = (ulo[k], uhi[k])
            vol[i] = uvol[k]
            alive[cand[k]] = False
            merged_any = True
        arr, alive = arr[alive], alive[alive]
        if not merged_any:
            break
    if len(arr) > max_boxes:

        def cost(a: np.ndarray, i: int, others: np.ndarray) -> np.ndarray:
            lo, hi = a[i]
            near = np.all(
                (a[others, 0] <= hi + touch_gap) & (a[others, 1] >= lo - touch_gap), axis=1
            )
            ulo = np.minimum(a[others, 0], lo)
            uhi = np.maximum(a[others, 1], hi)
            added = volume(ulo, uhi) - volume(lo, hi) - volume(a[others, 0], a[others, 1])
            if within is not None:
                near &= inside_any(ulo, uhi, within)
            return np.where(near, added, np.inf)

        def union(a: np.ndarray, b: np.ndarray) -> np.ndarray:
            return np.stack([np.minimum(a[0], b[0]), np.maximum(a[1], b[1])])

        def allowed(u: np.ndarray) -> bool:
            return not forbidden.intersects(u[None, 0], u[None, 1], margin)[0]

        arr = merge_cheapest(arr, max_boxes, cost, union, allowed)
    out = []
    for lo, hi in arr:
        t = _tight(lo, hi, index, 0.0)
        if t is not None:
            box = thicken(t[0], t[1], min_thickness, forbidden, margin)
            if within is not None:
                box = clip_to_envelope(box, np.stack(t), within)
            out.append(box)
    return out


#: Thickness (m) of a box squeezed between a surface and a sweep: thin enough for a
#: 1 mm play, thick enough for PhysX to cook (validation wants 0.1 mm).
SQUEEZED_THICKNESS = 0.0003


def inside_any(lo: np.ndarray, hi: np.ndarray, within: np.ndarray, eps: float = 1e-9) -> np.ndarray:
    """(N,) True where box [lo[i], hi[i]] lies inside one of ``within`` (K, 2, 3)."""
    return np.any(
        np.all(lo[:, None] >= within[None, :, 0] - eps, axis=2)
        & np.all(hi[:, None] <= within[None, :, 1] + eps, axis=2),
        axis=1,
    )


def clip_to_envelope(box: np.ndarray, core: np.ndarray, within: np.ndarray) -> np.ndarray:
    """``box`` (2, 3) clipped to the first of ``within`` that holds ``core`` (its box
    before thickening); unchanged when none does."""
    for env in within:
        if np.all(core[0] >= env[0] - 1e-9) and np.all(core[1] <= env[1] + 1e-9):
            return np.stack([np.maximum(box[0], env[0]), np.minimum(box[1], env[1])])
    return box


def thicken(
    lo: np.ndarray, hi: np.ndarray, min_thickness: float, forbidden: HullSet, margin: float
) -> np.ndarray:
    """(2, 3) ``[lo, hi]`` grown to ``min_thickness`` along its thin axes, centred when that
    stays off ``forbidden``, else on whichever side does (a wall 1 mm from a drawer grows
    away from the drawer), else only to SQUEEZED_THICKNESS."""
    lo, hi = lo.copy(), hi.copy()
    for k in np.nonzero((hi - lo) < min_thickness)[0]:
        need = min_thickness - (hi[k] - lo[k])
        options = ((0.5 * need, 0.5 * need), (0.0, need), (need, 0.0))
        for down, up in options:
            a, b = lo.copy(), hi.copy()
            a[k] -= down
            b[k] += up
            if not forbidden.intersects(a, b, margin)[0]:
                lo, hi = a, b
                break
        else:
            grow = max(0.0, 0.5 * (SQUEEZED_THICKNESS - (hi[k] - lo[k])))
            lo[k] -= grow
            hi[k] += grow
    return np.stack([lo, hi])


# --------------------------------------------------------------------------- the object


def _filled_points(occ_filled: np.ndarray, occ_surface: np.ndarray, grid: Grid) -> np.ndarray:
    """Corners of the cells filled as enclosed interior (not reached by samples)."""
    inner = occ_filled & ~occ_surface
    if not inner.any():
        return np.zeros((0, 3))
    c = grid.centres(inner)
    h = 0.5 * grid.pitch
    return np.concatenate([c - h, c + h])


def _voxel_boxes(
    keep: np.ndarray,
    blocked: np.ndarray,
    grid: Grid,
    cells: CellBounds,
    params: VoxelCollisionParams,
) -> list[np.ndarray]:
    """Boxes ((2, 3) bounds) of the cells ``keep``: runs, merged off ``blocked``, tightened."""
    if not keep.any():
        return []
    runs = np.array(_runs(keep), dtype=np.int64).reshape(-1, 6)
    merged = merge_boxes(
        runs,
        _Volume(keep),
        _Volume(blocked),
        params.merge_slack,
        params.max_pieces,
        params.merge_depth / grid.pitch,
    )
    return [tighten(b, grid, cells, params.min_thickness) for b in merged]


#: A movable part's boxes are swept as at most this many enclosing boxes.
SWEEP_ENVELOPES = 8


def envelopes(boxes: list[np.ndarray], k: int) -> list[np.ndarray]:
    """At most ``k`` boxes ((2, 3) bounds) enclosing ``boxes``: the pair whose bounding box
    adds the least volume is merged, until ``k`` remain."""
    out = [np.asarray(b, dtype=np.float64) for b in boxes]
    while len(out) > k:
        arr = np.array(out)
        lo = np.minimum(arr[:, None, 0], arr[None, :, 0])
        hi = np.maximum(arr[:, None, 1], arr[None, :, 1])
        vol = np.prod(arr[:, 1] - arr[:, 0], axis=1)
        added = np.prod(hi - lo, axis=2) - vol[:, None] - vol[None, :]
        np.fill_diagonal(added, np.inf)
        i, j = np.unravel_index(int(np.argmin(added)), added.shape)
        merged = np.stack([lo[i, j], hi[i, j]])
        out = [b for n, b in enumerate(out) if n not in (i, j)] + [merged]
    return out


def shrink_envelopes(envelopes_: list[np.ndarray], boxes: list[np.ndarray]) -> list[np.ndarray]:
    """Each envelope shrunk to the bounding box of the ``boxes`` that lie in it (empty
    ones dropped): never larger than before, so a sweep of them never grows."""
    env = np.array(envelopes_)
    out = []
    arr = np.array(boxes).reshape(-1, 2, 3)
    for e in env:
        mine = arr[inside_any(arr[:, 0], arr[:, 1], e[None])] if len(arr) else arr
        if len(mine):
            out.append(np.stack([mine[:, 0].min(axis=0), mine[:, 1].max(axis=0)]))
    return out


def _decompose(
    obj: ArticulatedObject, params: VoxelCollisionParams, grid: Grid, deadline: float
) -> tuple[dict[str, list[np.ndarray]], dict[str, int]]:
    spacing = 0.5 * grid.pitch
    margin = params.margin
    min_size = 2.0 * params.min_thickness
    occ, pts = {}, {}
    for p in obj.parts:
        samples = surface_points(p.mesh, spacing)
        surface = grid.splat(samples)
        filled = fill_enclosed(surface)
        occ[p.name] = filled
        pts[p.name] = np.concatenate([samples, _filled_points(filled, surface, grid)])
        _check(deadline)
    movable = [p for p in obj.parts if p.joint is not None and p.joint.movable]
    no_block = np.zeros(grid.shape, bool)
    boxes: dict[str, list[np.ndarray]] = {}
    index: dict[str, PointIndex] = {}
    # 1. movable parts: their own voxels
    for p in movable:
        boxes[p.name] = _voxel_boxes(
            occ[p.name], no_block, grid, CellBounds(grid, pts[p.name]), params
        )
        index[p.name] = PointIndex(grid, pts[p.name])
        _check(deadline)
    # 2. the space each movable part needs: its boxes' envelopes swept, as exact hulls
    envelope: dict[str, list[np.ndarray]] = {}
    sweeps: dict[str, HullSet] = {}
    for p in movable:
        envelope[p.name] = envelopes(boxes[p.name], SWEEP_ENVELOPES)
        sweeps[p.name] = HullSet()
        swept_hulls(p.joint, envelope[p.name], sweeps[p.name])  # type: ignore[arg-type]
    # 3. every movable part stays off the others' sweeps (a drawer resting on the next
    # one parts from it by the margin; a door's edge clears its twin's swing), and
    # inside its own envelopes, so that its own sweep only shrinks
    for p in movable:
        others = HullSet.union(sweeps[q.name] for q in movable if q is not p)
        if len(others):
            kept = refine_boxes(boxes[p.name], index[p.name], others, margin, min_size)
            boxes[p.name] = merge_exact(
                kept, index[p.name], others, margin, params.merge_slack, params.max_pieces,
                params.min_thickness, grid.pitch, within=np.array(envelope[p.name]),
                depth=params.merge_depth,
            )  # fmt: skip
        _check(deadline)
    for p in movable:
        sweeps[p.name] = HullSet()
        tight = shrink_envelopes(envelope[p.name], boxes[p.name])
        swept_hulls(p.joint, tight, sweeps[p.name])  # type: ignore[arg-type]
    hulls = HullSet.union(sweeps.values())
    grow = ndimage.generate_binary_structure(3, 3)
    raw = np.zeros(grid.shape, bool)
    for p in movable:
        raw |= swept_occupancy(p, occ[p.name], grid)
        _check(deadline)
    blocked = ndimage.binary_dilation(raw, grow, iterations=max(1, params.clearance))
    # 4. the base: voxels off the dilated sweeps, plus its surface in the dilation's
    # margin that the exact sweeps leave free; tightened to free points only
    base = obj.base.name
    # points in the dilation's margin get the exact test; points deep inside the voxel
    # sweep (eroded) are inside the exact one too and are dropped
    idx, inside = grid.index(pts[base])
    cell = np.zeros(len(idx), np.int8)  # 0 free, 1 margin, 2 deep
    deep = ndimage.binary_erosion(raw, grow)
    i, j, k = idx[inside].T
    cell[inside] = np.where(deep[i, j, k], 2, np.where(blocked[i, j, k], 1, 0))
    near = pts[base][cell == 1]
    near = near[~hulls.intersects(near, near, margin)] if len(near) else near
    free = np.concatenate([pts[base][cell == 0], near])
    index[base] = PointIndex(grid, free)
    first = _voxel_boxes(occ[base] & ~blocked, blocked, grid, CellBounds(grid, free), params)
    recovered = []
    if len(near):
        near_cells = CellBounds(grid, near)
        for b in np.array(_runs(grid.splat(near)), dtype=np.int64).reshape(-1, 6):
            lo, hi = near_cells.of(b)
            recovered.append(np.stack([lo, hi]))
    _check(deadline)
    kept = refine_boxes(first + recovered, index[base], hulls, margin, min_size)
    _check(deadline)
    boxes[base] = merge_exact(
        kept, index[base], hulls, margin, params.merge_slack, params.max_pieces,
        params.min_thickness, grid.pitch, depth=params.merge_depth,
    )  # fmt: skip
    carved = {base: int((occ[base] & blocked).sum())}
    return boxes, carved


class _OutOfTime(Exception):
    pass


def _check(deadline: float) -> None:
    if time.perf_counter() > deadline:
        raise _OutOfTime


# --------------------------------------------------------------------------- measures


def distance_to_boxes(points: np.ndarray, boxes: list[np.ndarray]) -> np.ndarray:
    """(N,) distance (m) from each point to the nearest of ``boxes`` ((2, 3) bounds)."""
    best = np.full(len(points), np.inf)
    for lo, hi in boxes:
        d = np.maximum(np.maximum(lo - points, points - hi), 0.0)
        best = np.minimum(best, np.linalg.norm(d, axis=1))
    return best


def coverage(
    obj: ArticulatedObject,
    boxes: dict[str, list[np.ndarray]],
    spacing: float = 0.005,
    relative: float = 0.01,
    absolute: float = 0.005,
) -> dict[str, dict[str, float]]:
    """How well each part's boxes fit its surface, per part, both ways.

    Covering: surface samples (``spacing`` m apart) farther than the tolerance
    max(``absolute``, ``relative`` x the part's largest extent) from the part's boxes
    count as uncovered; the base's samples inside another part's swept space (the exact
    hulls of that part's boxes) are left out: no piece may cover them. Overfill: points
    on a ``spacing`` lattice inside the boxes that lie farther than the tolerance from
    the part's surface and outside the cavities its surface encloses (a closed door is
    solid) count as overfill (a box bridging a handle and the door's far edge).

    Returns per part ``uncovered`` (fraction), ``p95`` and ``max`` distance (m),
    ``tolerance`` (m), ``excluded`` (fraction), ``overfill`` (fraction of the boxes'
    volume) and ``overfill_max`` (m: the farthest box point from the surface).
    """
    from scipy.spatial import cKDTree

    hulls = HullSet()
    for p in obj.parts:
        if p.joint is not None and p.joint.movable:
            swept_hulls(p.joint, boxes[p.name], hulls)
    out = {}
    for p in obj.parts:
        samples = surface_points(p.mesh, spacing)
        excluded = np.zeros(len(samples), bool)
        if p.joint is None and len(hulls):
            excluded = hulls.intersects(samples, samples, 0.0)
        kept = samples[~excluded]
        d = distance_to_boxes(kept, boxes[p.name]) if len(kept) else np.zeros(1)
        tol = max(absolute, relative * float(np.ptp(p.mesh.vertices, axis=0).max()))
        over, over_max = _overfill(p.mesh, boxes[p.name], spacing, tol, cKDTree)
        out[p.name] = {
            "uncovered": float((d > tol).mean()),
            "p95": float(np.percentile(d, 95)),
            "max": float(d.max()),
            "tolerance": tol,
            "excluded": float(excluded.mean()),
            "overfill": over,
            "overfill_max": over_max,
        }
    return out


def _overfill(
    mesh: trimesh.Trimesh, boxes: list[np.ndarray], spacing: float, tol: float, tree_type: type
) -> tuple[float, float]:
    """(fraction of the boxes' lattice points that are overfill, farthest distance).
    The surface is sampled at half the lattice spacing, so its voxels leave no gaps
    for the enclosed-cavity fill to leak through. Distances up to twice the tolerance
    are exact (to the samples); beyond, a distance transform of the surface's voxels
    gives them to about a lattice spacing (exact queries far from a large part's
    surface cost minutes)."""
    samples = surface_points(mesh, 0.5 * spacing)
    if not boxes or not len(samples):
        return 0.0, 0.0
    lo = np.minimum(samples.min(axis=0), np.min([b[0] for b in boxes], axis=0)) - 2 * spacing
    hi = np.maximum(samples.max(axis=0), np.max([b[1] for b in boxes], axis=0)) + 2 * spacing
    shape = tuple(int(n) for n in np.ceil((hi - lo) / spacing))
    grid = Grid(origin=lo, pitch=spacing, shape=shape)  # type: ignore[arg-type]
    surface = grid.splat(samples)
    solid = fill_enclosed(surface)
    coarse = ndimage.distance_transform_edt(~surface) * spacing
    tree = tree_type(samples)
    total, far, farthest = 0, 0, 0.0
    for b_lo, b_hi in boxes:
        n = np.maximum(np.ceil((b_hi - b_lo) / spacing).astype(int), 1)
        axes = [b_lo[k] + (np.arange(n[k]) + 0.5) * (b_hi[k] - b_lo[k]) / n[k] for k in range(3)]
        pts = np.stack(np.meshgrid(*axes, indexing="ij"), -1).reshape(-1, 3)
        dist, _ = tree.query(pts, distance_upper_bound=2 * tol)
        idx, inside = grid.index(pts)
        i, j, k = np.clip(idx, 0, np.array(shape) - 1).T
        unbounded = ~np.isfinite(dist)
        dist[unbounded] = np.maximum(coarse[i, j, k][unbounded], 2 * tol)
        in_solid = solid[i, j, k] & inside
        bad = (dist > tol) & ~in_solid
        total += len(pts)
        far += int(bad.sum())
        if bad.any():
            farthest = max(farthest, float(dist[bad].max()))
    return far / total, farthest


# --------------------------------------------------------------------------- cache


def default_cache_dir() -> Path:
    """``$PACT_CACHE_DIR/voxel`` if set, else ``~/.cache/pact/voxel``."""
    env = os.environ.get("PACT_CACHE_DIR")
    return (Path(env) if env else Path.home() / ".cache" / "pact") / "voxel"


def cache_key(obj: ArticulatedObject, params: VoxelCollisionParams) -> str:
    """Hex sha256 of every part's mesh arrays and joint, and the parameters."""
    h = hashlib.sha256(f"voxel-collision-{CACHE_VERSION}".encode())
    h.update(json.dumps(asdict(params), sort_keys=True).encode())
    for p in obj.parts:
        h.update(p.name.encode())
        h.update(np.ascontiguousarray(p.mesh.vertices, dtype=np.float64).tobytes())
        h.update(np.ascontiguousarray(p.mesh.faces, dtype=np.int64).tobytes())
        h.update(json.dumps(None if p.joint is None else p.joint.to_json()).encode())
    return h.hexdigest()


def _save(path: Path, boxes: dict[str, list[np.ndarray]], pitch: float) -> None:
    buf = io.BytesIO()
    arrays = {f"part_{k}": np.array(v).reshape(-1, 2, 3) for k, v in enumerate(boxes.values())}
    np.savez(buf, names=np.array(list(boxes)), pitch=pitch, **arrays)
    atomic_write_bytes(path, buf.getvalue())


def _load(path: Path) -> tuple[dict[str, list[np.ndarray]], float]:
    with np.load(path) as z:
        names = [str(n) for n in z["names"]]
        return {n: list(z[f"part_{k}"]) for k, n in enumerate(names)}, float(z["pitch"])


# --------------------------------------------------------------------------- entry


def articulated_boxes(
    obj: ArticulatedObject,
    params: VoxelCollisionParams = DEFAULT_PARAMS,
    cache_dir: Path | None = None,
) -> tuple[dict[str, list[np.ndarray]], float, bool]:
    """Collision boxes (2, 3) bounds per part of a metric ``obj`` (object frame), the
    pitch used and whether they came from the cache. See the module docstring."""
    cache_dir = default_cache_dir() if cache_dir is None else Path(cache_dir)
    path = cache_dir / f"{cache_key(obj, params)}.npz"
    if path.is_file():
        try:
            boxes, pitch = _load(path)
            return boxes, pitch, True
        except Exception as e:  # noqa: BLE001 - a damaged cache entry is recomputed
            log.warning("ignoring unreadable collision cache entry %s: %s", path, e)
    scale = 1.0
    while True:
        grid = make_grid(obj, params, scale)
        last = scale >= FALLBACK_SCALE
        deadline = math.inf if last else time.perf_counter() + params.timeout
        try:
            boxes, _ = _decompose(obj, params, grid, deadline)
            break
        except _OutOfTime:
            log.warning(
                "voxel collision over %g s at pitch %.4f m; retrying at twice the pitch",
                params.timeout,
                grid.pitch,
            )
            scale *= 2
    _save(path, boxes, grid.pitch)
    return boxes, grid.pitch, False


def articulated_pieces(
    obj: ArticulatedObject,
    params: VoxelCollisionParams = DEFAULT_PARAMS,
    cache_dir: Path | None = None,
) -> VoxelCollisionResult:
    """:func:`articulated_boxes` as box meshes per part (object frame)."""
    t0 = time.perf_counter()
    boxes, pitch, cached = articulated_boxes(obj, params, cache_dir)
    pieces = {name: [box_mesh(b) for b in bs] for name, bs in boxes.items()}
    return VoxelCollisionResult(
        pieces=pieces, pitch=pitch, seconds=time.perf_counter() - t0, cached=cached
    )

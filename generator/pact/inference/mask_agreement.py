"""How well a sample of part voxels agrees with the input's part mask (render and compare).

Stage 1 samples part structures from noise; with the small model, samples for the same
image and mask differ a lot (a drawer in the wrong row, a part left empty, the base
swallowing a door). :func:`agreement` scores one sample against the 2-D part mask the
user gave: the sample's surface voxels are rendered as a part-id image (orthographic,
nearest voxel wins) from each of a grid of views round the front of the object
(azimuth +-60 degrees, elevation 0-40 degrees: the range in which the training renders
and photos of furniture show the front), both that render and the mask are cropped to
their own silhouette's bounding box and resampled to ``G`` x ``G``, and the score is the
best view's mean over the mask's part ids of the per-id IoU. Cropping each to its own box
removes scale, position and aspect (the photo's camera distance and field of view are
unknown), so the score compares the layout of the parts, not the object's size.

The stage-1 generator (``stage1_generator.Stage1Generator``) draws several samples per
image and keeps the one that realizes the mask's parts and agrees with it best; a part
the mask shows and the kept sample leaves empty is then carved out of the base where the
mask puts it (:func:`carve_missing`), misplaced parts are moved to where the mask puts
them (:func:`relabel_front`), and, since the score is blind to proportions, the sample's
height is fitted to the aspect of the mask's silhouette (:func:`fit_height`). Without a
mask, :func:`sample_mask` makes one from a sample and the photo's silhouette: the
sample's parts as seen from the view whose silhouette agrees best.

Ground-truth part voxels score 0.66 on average against the masks of the 42 test-split
renders (0.32-0.83; the renders are perspective, the score's views orthographic); against
the mask of another object of the same category, 0.49. About 0.15-0.25 s per sample on
one core.
"""

from __future__ import annotations

import os
from collections.abc import Callable, Sequence
from concurrent.futures import ThreadPoolExecutor
from typing import TypeVar

import numpy as np
from scipy import ndimage

GRID = 40  # G: the side of the compared id images, in pixels
PIXEL_MIN = 0.7  # voxels: the smallest pixel a sample is rendered with
COLUMN_GRID = 160  # pixels: the side of the mask image the front's columns are read from
MISPLACED_IOU = 0.85  # a part overlapping its mask pixels less than this is moved
#: (short, long) voxels across the front that a moved part keeps, else it is not moved:
#: on the 32-voxel grid of a unit object, the box layout's 5 cm smallest face (10 cm for
#: the other side of a shallow one) at an object's typical 1-1.5 m
MIN_FRONT_VOXELS = (2, 4)
CARVE_DEPTH = 2  # voxels: depth of a carved part when no other movable part sets it
AZIMUTHS_DEG = (-60.0, -45.0, -30.0, -15.0, 0.0, 15.0, 30.0, 45.0, 60.0)
ELEVATIONS_DEG = (0.0, 10.0, 20.0, 30.0, 40.0)


def view_rotation(azimuth: float, elevation: float) -> np.ndarray:
    """(3, 3) rows: image right, image down, towards the camera, for a camera at
    ``azimuth`` (radians, about +z from +x) and ``elevation`` (radians) looking at the
    origin with +z up (the object frame: front +x)."""
    ce = float(np.cos(elevation))
    d = (ce * float(np.cos(azimuth)), ce * float(np.sin(azimuth)), float(np.sin(elevation)))
    # right = -d x z, up = right x -d: the cross products written out (np.cross's
    # per-call overhead was a third of the box fit's time; same arithmetic, same bits)
    a = (-d[0], -d[1], -d[2])
    right = np.array([a[1] * 1.0 - a[2] * 0.0, a[2] * 0.0 - a[0] * 1.0, a[0] * 0.0 - a[1] * 0.0])
    right /= np.linalg.norm(right)
    r = right.tolist()
    up = (r[1] * a[2] - r[2] * a[1], r[2] * a[0] - r[0] * a[2], r[0] * a[1] - r[1] * a[0])
    return np.array([r, [-up[0], -up[1], -up[2]], list(d)])


VIEWS = tuple(
    view_rotation(np.radians(a), np.radians(e)) for e in ELEVATIONS_DEG for a in AZIMUTHS_DEG
)
# points per voxel: its centre +-0.3 along each axis (at most 0.6 voxels apart), so a
# pixel at least PIXEL_MIN voxels wide always holds one
_SPLAT = np.stack(np.meshgrid(*[(-0.3, 0.3)] * 3, indexing="ij"), -1).reshape(-1, 3)


def surface_points(occ: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Part occupancies (T, R, R, R) -> points (N, 3) in voxel units filling the voxels
    on the surface of their union (8 per voxel), their part ids (N,) (slot + 1) and the
    voxel each fills (N, 3) int."""
    occ = np.asarray(occ, bool)
    union = occ.any(axis=0)
    p = np.pad(union, 1)
    inner = p[1:-1, 1:-1, 1:-1].copy()
    for axis in range(3):
        for shift in (-1, 1):
            inner &= np.roll(p, shift, axis=axis)[1:-1, 1:-1, 1:-1]
    shell = union & ~inner
    labels = np.zeros(union.shape, np.int64)
    for k in range(len(occ)):
        labels[occ[k]] = k + 1
    idx = np.argwhere(shell)
    pts = (idx[:, None, :] + 0.5 + _SPLAT[None]).reshape(-1, 3)
    n = len(_SPLAT)
    return pts, np.repeat(labels[shell], n), np.repeat(idx, n, axis=0)


def render_visible(points: np.ndarray, view: np.ndarray, grid: int = GRID) -> np.ndarray:
    """(grid, grid) index of the point (``surface_points``) visible at each pixel (-1:
    background) seen along ``view`` (``view_rotation``), orthographic, cropped to the
    points' bounding box. Rendered at no more than one pixel per ``PIXEL_MIN`` voxels
    along each image axis (so the splatted points leave no holes), then resampled."""
    q = points @ view.T
    u, v, depth = q[:, 0], q[:, 1], q[:, 2]
    lo_u, lo_v = u.min(), v.min()
    span_u, span_v = u.max() - lo_u, v.max() - lo_v
    ru = int(min(max(np.ceil(span_u / PIXEL_MIN), 1), grid))
    rv = int(min(max(np.ceil(span_v / PIXEL_MIN), 1), grid))
    iu = ((u - lo_u) / max(span_u, 1e-9) * ru).astype(np.int64)
    iv = ((v - lo_v) / max(span_v, 1e-9) * rv).astype(np.int64)
    np.minimum(iu, ru - 1, out=iu)
    np.minimum(iv, rv - 1, out=iv)
    # far to near: the nearest is written last
    order = np.argsort(depth, kind="stable")
    img = np.full(rv * ru, -1, np.int64)
    img[(iv * ru + iu)[order]] = order
    r = (np.arange(grid) + 0.5) / grid
    return img.reshape(rv, ru)[(r * rv).astype(np.int64)][:, (r * ru).astype(np.int64)]


def render_ids(
    points: np.ndarray, ids: np.ndarray, view: np.ndarray, grid: int = GRID
) -> np.ndarray:
    """(grid, grid) part-id image (0 background) of ``points`` with ids ``ids``
    (``render_visible``)."""
    vis = render_visible(points, view, grid)
    return np.where(vis >= 0, ids[np.maximum(vis, 0)], 0)


def mask_ids(mask: np.ndarray, max_id: int, grid: int = GRID) -> np.ndarray:
    """A part mask (H, W) ids -> (grid, grid) ids cropped to its silhouette's bounding box
    (nearest sampling); ids above ``max_id`` (parts the model has no slot for) count as
    the base (1), as the stage-1 inputs treat them. Raises ValueError for an empty mask."""
    mask = np.asarray(mask)
    rows, cols = np.nonzero(mask)
    if len(rows) == 0:
        raise ValueError("the part mask is empty (all background)")
    m = mask[rows.min() : rows.max() + 1, cols.min() : cols.max() + 1].astype(np.int64)
    r = (np.arange(grid) + 0.5) / grid
    out = m[(r * m.shape[0]).astype(np.int64)][:, (r * m.shape[1]).astype(np.int64)]
    out[out > max_id] = 1
    return out


def id_iou(a: np.ndarray, b: np.ndarray, ids: np.ndarray) -> np.ndarray:
    """Per id in ``ids`` the IoU of the pixels labelled with it in ``a`` and in ``b``."""
    n = int(max(a.max(), b.max(), ids.max())) + 1
    inter = np.bincount(a[a == b], minlength=n)
    union = np.bincount(a.ravel(), minlength=n) + np.bincount(b.ravel(), minlength=n) - inter
    return inter[ids] / np.maximum(union[ids], 1)


def best_view(
    occ: np.ndarray,
    mask: np.ndarray,
    views: tuple[np.ndarray, ...] = VIEWS,
    grid: int = GRID,
) -> tuple[float, int]:
    """(score, index into ``views``) of the view in which part occupancies (T, R, R, R)
    (slot k <-> mask id k + 1) agree best with a part mask (H, W): the mean per-id IoU
    over the ids the mask shows (module docstring). (0, 0) when the occupancies are empty."""
    target = mask_ids(mask, len(occ), grid)
    ids = np.unique(target)
    ids = ids[ids > 0]
    pts, labels, _ = surface_points(occ)
    if len(pts) == 0 or len(ids) == 0:
        return 0.0, 0
    scores = [float(id_iou(render_ids(pts, labels, v, grid), target, ids).mean()) for v in views]
    best = int(np.argmax(scores))
    return scores[best], best


def agreement(
    occ: np.ndarray,
    mask: np.ndarray,
    views: tuple[np.ndarray, ...] = VIEWS,
    grid: int = GRID,
) -> float:
    """Score in [0, 1] of part occupancies against a part mask: ``best_view``'s score."""
    return best_view(occ, mask, views, grid)[0]


_T = TypeVar("_T")


def _on_threads(fn: Callable[[int], _T], n: int) -> list[_T]:
    """``[fn(0), ..., fn(n - 1)]``, on as many threads as there are cores (at most ``n``):
    the renders' sorts and products run in NumPy without the GIL, so several samples
    are scored at once (1.9 times faster on 2 cores, the same results)."""
    workers = min(n, os.cpu_count() or 1)
    if workers <= 1:
        return [fn(i) for i in range(n)]
    with ThreadPoolExecutor(workers) as pool:
        return list(pool.map(fn, range(n)))


def agreements(
    occs: Sequence[np.ndarray],
    mask: np.ndarray,
    views: tuple[np.ndarray, ...] = VIEWS,
    grid: int = GRID,
) -> list[float]:
    """:func:`agreement` of each of several samples' part occupancies with one mask."""
    return _on_threads(lambda i: agreement(occs[i], mask, views, grid), len(occs))


def sample_masks(
    occs: Sequence[np.ndarray], silhouettes: Sequence[np.ndarray], min_share: float = 0.005
) -> list[np.ndarray]:
    """:func:`sample_mask` of each sample against its photo's silhouette."""
    return _on_threads(
        lambda i: sample_mask(occs[i], silhouettes[i], min_share=min_share), len(occs)
    )


def _stretched(ids: np.ndarray, h: int, w: int) -> np.ndarray:
    """A (side, side) render of a bounding box stretched onto an (h, w) box (nearest)."""
    side = ids.shape[0]
    ri = ((np.arange(h) + 0.5) / h * side).astype(np.int64)
    ci = ((np.arange(w) + 0.5) / w * side).astype(np.int64)
    return ids[ri][:, ci]


def sample_mask(
    occ: np.ndarray,
    silhouette: np.ndarray,
    views: tuple[np.ndarray, ...] = VIEWS,
    min_share: float = 0.005,
) -> np.ndarray:
    """A part mask (H, W) for an image that came without one: the sample's part ids
    (slot k -> id k + 1) as seen from the view in which its silhouette agrees best with
    the image's ``silhouette`` (H, W) bool (``best_view``), stretched onto the
    silhouette's bounding box; silhouette pixels no part covers are the base (1), pixels
    off the silhouette 0. A part keeps its largest connected piece, the rest of its
    pixels are the base (a sample's part seen in scattered pieces would be laid out as
    one box spanning them all, through its neighbours); a part that then covers less
    than ``min_share`` of the silhouette counts as the base (a speck of a part is no
    part: the layout would give it a whole front cell). All zeros when the silhouette or
    the sample is empty.

    A silhouette cannot always tell a view from its mirror image (azimuth a against -a,
    the front on the other side): for a sample about as deep as it is wide, the parts
    may then land on the photo's side face (on the procedural test split's ovens)."""
    sil = np.asarray(silhouette, bool)
    out = np.zeros(sil.shape, np.int64)
    union = np.asarray(occ, bool).any(axis=0)
    if not sil.any() or not union.any():
        return out
    _, v = best_view(union[None], sil.astype(np.int64), views)
    rows, cols = np.nonzero(sil)
    r0, c0 = rows.min(), cols.min()
    h, w = rows.max() + 1 - r0, cols.max() + 1 - c0
    pts, labels, _ = surface_points(occ)
    ids = render_ids(pts, labels, views[v], int(max(h, w)))  # its bounding box
    out[r0 : r0 + h, c0 : c0 + w] = np.maximum(_stretched(ids, h, w), 1)
    out[~sil] = 0
    for k in np.unique(out):
        if k <= 1:
            continue
        pieces, n = ndimage.label(out == k, structure=np.ones((3, 3), bool))
        if n > 1:  # the largest piece only
            largest = 1 + int(np.argmax(np.bincount(pieces.ravel())[1:]))
            out[(pieces > 0) & (pieces != largest)] = 1
        if (out == k).sum() < min_share * sil.sum():
            out[out == k] = 1
    return out


def carve_missing(
    occ: np.ndarray,
    mask: np.ndarray,
    slots: list[int],
    views: tuple[np.ndarray, ...] = VIEWS,
    grid: int = GRID,
    depth: int = CARVE_DEPTH,
) -> np.ndarray:
    """Part occupancies (T, R, R, R) with each empty slot in ``slots`` (>= 1) carved out
    of the base (slot 0) where the part mask puts it.

    The mask lists the part, but the sample left it empty. In the view that agrees best
    with the mask (``best_view``), the base's visible voxels under the part's mask pixels
    become the part, with the base voxels behind them along the frame axis nearest the
    viewing direction, as deep as the median of the other movable parts along that axis
    (``depth`` voxels when there are none). Other movable parts are never taken from.
    Returns a new array; a slot whose pixels show no base voxel stays empty."""
    occ = np.array(occ, bool)
    missing = [k for k in slots if k >= 1 and not occ[k].any()]
    if not missing or not occ[0].any():
        return occ
    target = mask_ids(mask, len(occ), grid)
    _, v = best_view(occ, mask, views, grid)
    pts, labels, vox = surface_points(occ)
    vis = render_visible(pts, views[v], grid)
    axis = int(np.argmax(np.abs(views[v][2])))
    inward = -np.sign(views[v][2][axis])  # from the visible face into the object
    extents = [
        int(np.ptp(np.argwhere(occ[j])[:, axis])) + 1
        for j in range(1, len(occ))
        if j not in missing and occ[j].any()
    ]
    d = int(np.median(extents)) if extents else depth
    step = np.zeros(3, np.int64)
    step[axis] = int(inward)
    R = occ.shape[1]
    for k in missing:
        hit = vis[(target == k + 1) & (vis >= 0)]
        seeds = np.unique(vox[hit[labels[hit] == 1]], axis=0)  # visible base voxels
        if len(seeds) == 0:
            continue
        cells = (seeds[:, None, :] + np.arange(d)[None, :, None] * step).reshape(-1, 3)
        cells = cells[((cells >= 0) & (cells < R)).all(axis=1)]
        cells = cells[occ[0][tuple(cells.T)]]
        occ[k][tuple(cells.T)] = True
        occ[0][tuple(cells.T)] = False
    return occ


def _front_columns(union: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """(y, z) index pairs (N, 2) of the columns along x that hold a voxel of ``union``
    (R, R, R), and the x index (N,) of each column's frontmost (+x) voxel."""
    cols = union.any(axis=0)
    yz = np.argwhere(cols)
    R = union.shape[0]
    front = R - 1 - np.argmax(union[::-1, yz[:, 0], yz[:, 1]], axis=0)
    return yz, front


def _move_parts(
    occ: np.ndarray,
    movable: list[int],
    moved: list[int],
    yz: np.ndarray,
    front: np.ndarray,
    column_id: np.ndarray,
    depths: dict[int, int],
) -> np.ndarray:
    """``relabel_front``'s move: the parts in ``moved`` leave the columns the mask gives
    elsewhere (to the base) and take, in each of their own columns, the unbroken run of
    occupied voxels from the front back, at most ``depths[k]`` deep (a drawer's front
    panel, and its sides and bottom where they continue it, not a separate piece behind
    it; in a column on the rim of the object's front, where the base's own wall runs
    back, only as deep as in its inner columns). Of what a part takes, the piece reaching
    furthest to the front is kept, the rest goes to the base. The other movable parts'
    voxels are never taken."""
    union = occ.any(axis=0)
    kept = np.zeros(union.shape, bool)  # voxels of the parts placed well
    for k in movable:
        if k not in moved:
            kept |= occ[k]
    out = occ.copy()
    col_of = np.full(union.shape[1:], -1, np.int64)  # (y, z) -> mask id of the column
    col_of[yz[:, 0], yz[:, 1]] = column_id
    for k in moved:
        wrong = out[k] & (col_of[None] != k + 1)
        out[0] |= wrong
        out[k] &= ~wrong
    free = union & ~kept
    cols = union.any(axis=0)  # the object's front footprint (y, z)
    p = np.pad(cols, 1)
    footprint_inner = cols & p[:-2, 1:-1] & p[2:, 1:-1] & p[1:-1, :-2] & p[1:-1, 2:]
    for k in moved:
        sel = column_id == k + 1
        if not sel.any():
            continue
        cy, cz, cf = yz[sel, 0], yz[sel, 1], front[sel]
        t = np.arange(depths[k])
        x = cf[:, None] - t[None, :]  # (n, d): from the front back
        inside = x >= 0
        run = np.cumprod(inside & free[np.maximum(x, 0), cy[:, None], cz[:, None]], axis=1)
        # a column on the rim of the object's front is the base's side, top or bottom
        # wall running back: there the part is only as deep as in its inner columns
        rim = ~footprint_inner[cy, cz]
        inner_runs = run[~rim].sum(axis=1)
        rim_depth = max(int(np.median(inner_runs)), 1) if len(inner_runs) else 1
        run[rim, rim_depth:] = 0
        i, j = np.nonzero(run)  # the unbroken run of voxels from the front, per column
        x, y, z = x[i, j], cy[i], cz[i]
        out[:, x, y, z] = False
        out[k, x, y, z] = True
        front_piece = _frontmost_piece(out[k])
        out[0] |= out[k] & ~front_piece
        out[k] = front_piece
    return out


def _frontmost_piece(part: np.ndarray) -> np.ndarray:
    """The 26-connected piece of a part occupancy (R, R, R) that reaches furthest to the
    front (+x; the larger on a tie): a moved part is one rigid piece on the front."""
    from scipy import ndimage

    labels, n = ndimage.label(part, structure=np.ones((3, 3, 3), bool))
    if n <= 1:
        return part.copy()
    idx = np.argwhere(labels)
    lab = labels[tuple(idx.T)]
    reach = np.full(n + 1, -1)
    np.maximum.at(reach, lab, idx[:, 0])
    size = np.bincount(lab, minlength=n + 1)
    best = max(range(1, n + 1), key=lambda i: (reach[i], size[i]))
    return labels == best


def _openable(part: np.ndarray) -> bool:
    """Whether a part occupancy (R, R, R) keeps, in its largest 26-connected piece (what
    ``stage1.tidy_parts`` keeps), a front of at least ``MIN_FRONT_VOXELS`` (short side,
    long side) voxels: less is a face the box layout merges into the base."""
    from scipy import ndimage

    labels, n = ndimage.label(part, structure=np.ones((3, 3, 3), bool))
    if n == 0:
        return False
    largest = labels == int(np.argmax(np.bincount(labels.ravel())[1:])) + 1
    idx = np.argwhere(largest)
    ext = sorted(int(np.ptp(idx[:, a])) + 1 for a in (1, 2))  # across the front (y, z)
    return ext[0] >= MIN_FRONT_VOXELS[0] and ext[1] >= MIN_FRONT_VOXELS[1]


def relabel_front(
    occ: np.ndarray,
    mask: np.ndarray,
    slots: list[int],
    views: tuple[np.ndarray, ...] = VIEWS,
    grid: int = GRID,
    depth: int = CARVE_DEPTH,
    max_depth_share: float = 0.9,
    misplaced_iou: float = MISPLACED_IOU,
) -> np.ndarray:
    """Part occupancies (T, R, R, R) whose misplaced movable parts are moved to where the
    part mask puts them on the object's front (+x), keeping the union of all parts.

    In the view that agrees best with the mask (``best_view``), a movable slot ``k`` in
    ``slots`` whose rendered pixels overlap the mask's pixels of id ``k + 1`` by less
    than ``misplaced_iou`` (IoU) is misplaced: a drawer in the wrong row, a door spread
    over its neighbour. The frontmost voxel of every column along x is projected into the
    mask (cropped as the render is, resampled to ``COLUMN_GRID`` pixels: a drawer a few
    voxels tall keeps its rows), and the id there labels the column. A misplaced part
    loses its voxels in columns the mask gives to something else (to the base) and takes
    the voxels of the columns the mask gives it (``_move_parts``), at most as deep as it
    is in the sample (its x extent; the median of the other movable parts' when it is
    empty, ``depth`` voxels when all are; at most ``max_depth_share`` of the object's
    depth). A part that would keep less than ``MIN_FRONT_VOXELS`` across the front (a
    drawer the mask draws a voxel tall) is not moved. Parts placed well enough are left
    alone, their voxels neither moved nor taken: the orthographic views and the coarse
    grid make even a right layout score only about 0.66. Parts stay disjoint.

    Returns a new array; ``occ`` itself (a copy) when nothing is misplaced, or the
    relabelling would leave a slot of ``slots`` that the sample has empty, or agrees
    worse with the mask than the sample does.
    """
    occ = np.array(occ, bool)
    movable = [k for k in slots if 1 <= k < len(occ)]
    union = occ.any(axis=0)
    if not movable or not union.any():
        return occ
    before, v = best_view(occ, mask, views, grid)
    view = views[v]
    pts, labels, _ = surface_points(occ)
    ious = id_iou(
        render_ids(pts, labels, view, grid),
        mask_ids(mask, len(occ), grid),
        np.array([k + 1 for k in movable]),
    )
    moved = [k for k, iou in zip(movable, ious, strict=True) if iou < misplaced_iou]
    if not moved:
        return occ
    fine = COLUMN_GRID  # columns are projected one point each: no splatting holes
    target = mask_ids(mask, len(occ), fine)
    q = pts @ view.T
    lo, hi = q[:, :2].min(axis=0), q[:, :2].max(axis=0)
    yz, front = _front_columns(union)
    centres = np.column_stack([front, yz]).astype(np.float64) + 0.5
    uv = ((centres @ view.T)[:, :2] - lo) / np.maximum(hi - lo, 1e-9) * fine
    uv = np.clip(uv.astype(np.int64), 0, fine - 1)
    column_id = target[uv[:, 1], uv[:, 0]]  # mask id per column

    object_depth = int(np.ptp(np.argwhere(union)[:, 0])) + 1
    extents = {k: int(np.ptp(np.argwhere(occ[k])[:, 0])) + 1 for k in movable if occ[k].any()}
    fallback = int(np.median(list(extents.values()))) if extents else depth
    cap = max(1, int(max_depth_share * object_depth))
    depths = {k: min(extents.get(k, fallback), cap) for k in moved}
    while True:  # a part the mask's region makes too small to open stays where it was
        out = _move_parts(occ, movable, moved, yz, front, column_id, depths)
        small = [k for k in moved if occ[k].any() and not _openable(out[k])]
        if not small:
            break
        moved = [k for k in moved if k not in small]
        if not moved:
            return occ
    had = [k for k in movable if occ[k].any()]
    if any(not out[k].any() for k in had):
        return occ
    if agreement(out, mask, views, grid) < before:
        return occ
    return out


#: Height factors ``fit_height`` may apply (a sample is at most this much too flat or tall)
HEIGHT_SCALE_RANGE = (1.0 / 3.0, 3.0)
#: ... and it leaves a sample alone when its factor is within this of 1 (|log| below)
HEIGHT_SCALE_TOLERANCE = 0.4


def _silhouette_aspect(points: np.ndarray, view: np.ndarray) -> float:
    """Width over height of the orthographic projection of ``points`` (N, 3) in ``view``."""
    q = points @ view.T
    return float(np.ptp(q[:, 0]) / max(np.ptp(q[:, 1]), 1e-9))


def height_scale(
    occ: np.ndarray,
    mask: np.ndarray,
    views: tuple[np.ndarray, ...] = VIEWS,
    grid: int = GRID,
) -> float:
    """The factor on a sample's height (z) that gives its silhouette, in the view that
    agrees best with the part mask (``best_view``), the aspect (width over height) of
    the mask's silhouette; clipped to ``HEIGHT_SCALE_RANGE``. The agreement score crops
    both silhouettes to their own boxes, so it is blind to the object's proportions:
    stage 1 on a photo of a tall nightstand may draw a wide, low desk, on a microwave a
    box twice too tall, and keep that sample. 1.0 when the occupancy is empty."""
    union = np.asarray(occ, bool).any(axis=0)
    if not union.any():
        return 1.0
    _, v = best_view(occ, mask, views, grid)
    view = views[v]
    rows, cols = np.nonzero(np.asarray(mask))
    target = (np.ptp(cols) + 1) / (np.ptp(rows) + 1)
    # the occupied cells' corners: their projection spans the sample's silhouette
    cube = np.stack(np.meshgrid(*[(0.0, 1.0)] * 3, indexing="ij"), -1).reshape(-1, 3)
    corners = (np.argwhere(union)[:, None, :] + cube[None]).reshape(-1, 3)
    lo, hi = np.log(HEIGHT_SCALE_RANGE[0]), np.log(HEIGHT_SCALE_RANGE[1])
    for _ in range(40):  # the aspect falls as the height grows
        mid = 0.5 * (lo + hi)
        if _silhouette_aspect(corners * np.array([1.0, 1.0, np.exp(mid)]), view) > target:
            lo = mid
        else:
            hi = mid
    return float(np.exp(0.5 * (lo + hi)))


def rescale_height(occ: np.ndarray, factor: float) -> np.ndarray:
    """Part occupancies (T, R, R, R) with the object's height (z) multiplied by
    ``factor``, then scaled as a whole so that its longest side spans the grid again
    (the stage-1 normalization), centred on the grid. Each source voxel fills every
    target voxel its scaled cell touches, so a one-voxel panel survives a squash; a voxel
    two parts reach goes to the movable part, the lower slot first (``stage1.tidy_parts``'
    rule)."""
    occ = np.asarray(occ, bool)
    T, R = occ.shape[0], occ.shape[1]
    union = occ.any(axis=0)
    if not union.any() or factor == 1.0:
        return occ.copy()
    idx = np.argwhere(union)
    lo, hi = idx.min(axis=0).astype(np.float64), idx.max(axis=0) + 1.0
    stretch = np.array([1.0, 1.0, factor])
    scale = stretch * (R / ((hi - lo) * stretch).max())  # per axis, source -> target cells
    # centred on the grid by whole cells: an axis scaled by 1 maps cells onto cells
    offset = np.floor((R - (hi - lo) * scale) / 2.0 + 1e-6)
    out = np.zeros_like(occ)
    for k in [0, *range(T - 1, 0, -1)]:  # base first; lower movable slots win last
        cells = np.argwhere(occ[k]).astype(np.float64)
        if len(cells) == 0:
            continue
        a = (cells - lo) * scale + offset
        b = (cells + 1.0 - lo) * scale + offset
        first = np.clip(np.floor(a + 1e-6), 0, R - 1).astype(np.int64)
        last = np.clip(np.ceil(b - 1e-6) - 1, 0, R - 1).astype(np.int64)
        last = np.maximum(last, first)
        span = int((last - first).max()) + 1
        offs = np.stack(np.meshgrid(*[np.arange(span)] * 3, indexing="ij"), -1).reshape(-1, 3)
        tgt = first[:, None, :] + offs[None]
        keep = (tgt <= last[:, None, :]).all(axis=2)
        tgt = tgt[keep]
        if k > 0:
            out[:, tgt[:, 0], tgt[:, 1], tgt[:, 2]] = False
        out[k, tgt[:, 0], tgt[:, 1], tgt[:, 2]] = True
    return out


def fit_height(
    occ: np.ndarray,
    mask: np.ndarray,
    views: tuple[np.ndarray, ...] = VIEWS,
    grid: int = GRID,
) -> tuple[np.ndarray, float]:
    """(occupancies, factor): ``occ`` with its height fitted to the mask's silhouette
    (``height_scale``, ``rescale_height``); ``occ`` itself (a copy) and 1.0 when the
    factor is within ``HEIGHT_SCALE_TOLERANCE`` (in log) of 1."""
    factor = height_scale(occ, mask, views, grid)
    if abs(np.log(factor)) < HEIGHT_SCALE_TOLERANCE:
        return np.array(occ, bool), 1.0
    return rescale_height(occ, factor), factor

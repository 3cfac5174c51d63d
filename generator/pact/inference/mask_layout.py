"""The object's box and the photo's camera fitted to the part mask, and the movable parts
laid out on that box's front where the mask puts them.

On real photos the small stage-1 model gets the parts' layout wrong more often than
anything else: a chest's drawers in the wrong rows or spread over two rows, a
nightstand's door drawn on its side, walls left full of holes. Yet the part mask and the
silhouette look the same in a photo and in a render, and for the furniture and
appliances this project makes they pin the layout down: the object is close to a box, its
movable parts sit on its front, and the camera is a three-quarter view.

:func:`fit_box_camera` fits a box (its depth and height over its width) and a pinhole
camera (azimuth, elevation; an assumed ``FOVY`` of 45 degrees: product photos use
30-60) to the mask: the box's rendered silhouette against the mask's (both cropped to
their own bounding square: the photo's scale and framing are unknown), plus the share of
the movable parts' pixels that fall on the box's front face (so the front is the face
the parts are on). A coarse grid of views and proportions, then a coordinate search from
the best few. Given the photo, a second search adds where the photo shows the edge
between the box's front and its side (:func:`edge_score`: a box's faces are lit
differently, so that edge shows where the silhouette cannot place it; a tall narrow box
seen from 45 degrees has nearly the silhouette of a deeper one seen from 25), and its
fit is taken unless it explains the silhouette clearly worse (``EDGE_IOU_SLACK``). A
legged table or desk (silhouette IoU below ``BOX_IOU``) has no such edge: between its
legs there is only background, so its fit stays the silhouette's. On the 76 real product renders of the dev split (DEVELOPERS.md) with the
box's depth left free: azimuth within 4 degrees of the true camera's (median), elevation
within 2, height over width within 8 %, depth over width within 18 %. A near-frontal
view says little about depth, and the free depth comes out too shallow more often than
not, so :func:`layout_from_mask` takes the depth from the stage-1 samples: each
candidate's depth is fitted in turn, the rest free, and the one whose box explains the
silhouette best is kept; the parts-on-the-front share is left out of that choice (a
shallower box's larger front holds the parts as well), and of fits within
``DEPTH_TIE_IOU`` of the best the deepest wins (on the real dev split's photos, mean
absolute log error of depth over width, product / rooms: the kept sample's own depth
0.235 / 0.254, the best fit's 0.175 / 0.206 leaning shallow by 0.08, with the tie rule
0.153 / 0.186). It fits the depth freely when the camera
looks down on the top by ``DEPTH_FREE_ELEVATION`` or more, the freed depth explains the
silhouette clearly better, by ``DEPTH_FREE_GAIN`` of IoU, and the box turns by no more
than ``DEPTH_FREE_TURN`` for it.

:func:`layout_from_mask` then rebuilds the sample's part grids: the base is the box,
carved where the camera sees background through it (a desk's kneehole, the space
between a table's legs), each movable part takes the cells of the front face whose
centres project into its mask pixels, as deep as the sample drew it, and a panel (a
part at most ``PANEL_SHARE`` of the box's depth deep: a door) leaves a cavity behind it
inside the base's walls. Stage 2 then decodes these grids like any others.
"""

from __future__ import annotations

import functools
from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np
from scipy import ndimage

from generator.pact.inference.mask_agreement import CARVE_DEPTH, view_rotation

FOVY = np.radians(45.0)  # the assumed camera's vertical field of view
FIT_RASTERS = (24, 40)  # silhouette raster side: the coarse grid, the refinement
CONTAINMENT_WEIGHT = 0.5  # weight of the parts-on-the-front share against silhouette IoU
AZIMUTHS_DEG = np.arange(-70.0, 71.0, 10.0)
ELEVATIONS_DEG = np.arange(0.0, 51.0, 10.0)
DEPTH_RANGE = (0.25, 2.5)  # box depth over width searched when the depth is free
HEIGHT_RANGE = (0.2, 4.0)  # box height over width
REFINE_STARTS = 6  # coarse candidates refined
MIN_FIT_IOU = 0.5  # below this silhouette IoU the object is no box: the layout is not used
#: the box's depth is fitted too (not the sample's) when that raises the silhouette IoU by
#: more than ``DEPTH_FREE_GAIN``, both fits look down on the box's top by at least
#: ``DEPTH_FREE_ELEVATION`` (the top face is what shows the depth) and their azimuths
#: differ by at most ``DEPTH_FREE_TURN`` (seen from the side alone, depth trades against
#: azimuth: a fit that turns the box further has slid along that trade, not read depth)
DEPTH_FREE_GAIN = 0.02
#: of several given depths (the stage-1 candidates'), those whose fits' silhouette IoUs
#: are within this of the best are a tie, and the deepest of them is taken: the
#: silhouette alone leans shallow (module docstring)
DEPTH_TIE_IOU = 0.005
DEPTH_FREE_ELEVATION = np.radians(15.0)
DEPTH_FREE_TURN = np.radians(12.0)
#: below this silhouette IoU the object is a box only roughly (legs, an overhanging top): the
#: base also keeps to the sample's own cells (grown by ``SAMPLE_MARGIN``), since one view
#: carves only a wedge behind each leg
BOX_IOU = 0.85
SAMPLE_MARGIN = 1
SILHOUETTE_MARGIN = 2  # pixels the silhouette grows by before it carves the base
PANEL_SHARE = 0.35  # a part at most this share of the box's depth deep is a panel (door)
MAX_DEPTH_SHARE = 0.9  # no part is deeper than this share of the box's depth
#: weight of the photo's edge term (:func:`edge_score`, capped at ``EDGE_CAP`` and divided
#: by it) against the silhouette IoU in a second refinement; its fit is kept when its
#: silhouette IoU is within ``EDGE_IOU_SLACK`` of the first's (the silhouette's alone)
EDGE_WEIGHT = 0.2
EDGE_CAP = 3.0
EDGE_IOU_SLACK = 0.02
#: the photo is cropped to the silhouette's bounding square (``EDGE_PAD`` of its side
#: around it) and resampled to ``EDGE_SIDE`` pixels before its gradient is taken
#: (Gaussian ``EDGE_SIGMA`` pixels); an edge counts only where it is at least
#: ``EDGE_INSET`` pixels inside the silhouette (an edge on the outline is the silhouette's)
EDGE_SIDE = 192
EDGE_PAD = 0.1
EDGE_SIGMA = 1.5
EDGE_INSET = 4
EDGE_SAMPLES = 24  # points read along each edge, over its middle 70 %

# the box's 8 corners (signs along x, y, z) and its four faces a camera in front sees
_CORNERS = np.array([[sx, sy, sz] for sx in (-1, 1) for sy in (-1, 1) for sz in (-1, 1)], float)


def _corner(sx: int, sy: int, sz: int) -> int:
    return (sx > 0) * 4 + (sy > 0) * 2 + (sz > 0)


_FACES = {
    "front": [_corner(1, -1, -1), _corner(1, 1, -1), _corner(1, 1, 1), _corner(1, -1, 1)],
    "left": [_corner(-1, 1, -1), _corner(1, 1, -1), _corner(1, 1, 1), _corner(-1, 1, 1)],
    "right": [_corner(-1, -1, -1), _corner(1, -1, -1), _corner(1, -1, 1), _corner(-1, -1, 1)],
    "top": [_corner(-1, -1, 1), _corner(1, -1, 1), _corner(1, 1, 1), _corner(-1, 1, 1)],
}

_FACE_CORNERS = np.array([_FACES[name] for name in ("front", "left", "right", "top")])


@dataclass(frozen=True)
class BoxCamera:
    """A box (width 1 along y, ``depth`` along x, ``height`` along z, centred on the
    origin, front +x) seen by a pinhole camera at ``azimuth`` and ``elevation``
    (radians, ``mask_agreement.view_rotation``) looking at its centre from far enough
    that the box fills ``fovy``; ``iou`` is the fit's silhouette IoU. ``pixel_centre``
    (col, row) and ``pixel_side`` are the centre and side of the mask silhouette's
    bounding square, which the box's projected bounding square maps onto."""

    azimuth: float
    elevation: float
    depth: float
    height: float
    fovy: float
    iou: float
    pixel_centre: tuple[float, float]
    pixel_side: float

    @property
    def half_extents(self) -> np.ndarray:
        return np.array([self.depth / 2, 0.5, self.height / 2])

    def _plane(self, points: np.ndarray) -> np.ndarray:
        return _project(
            points[None], self.azimuth, self.elevation, self.half_extents[None], self.fovy
        )[0]

    def to_pixels(self, points: np.ndarray) -> np.ndarray:
        """(N, 2) mask pixel coordinates (col, row; pixel i spans [i, i + 1)) of box-frame
        points (N, 3)."""
        corners = self._plane(_CORNERS * self.half_extents)
        lo, hi = corners.min(axis=0), corners.max(axis=0)
        centre, side = (lo + hi) / 2, float((hi - lo).max())
        p = self._plane(np.asarray(points, float))
        return np.asarray(self.pixel_centre) + (p - centre) / side * self.pixel_side


def _project(
    points: np.ndarray, azimuth: float, elevation: float, half: np.ndarray, fovy: float
) -> np.ndarray:
    """Image-plane coordinates (B, N, 2) (right, down) of points (B, N, 3) of B boxes with
    half extents ``half`` (B, 3), each seen from the distance at which it fills ``fovy``."""
    R = view_rotation(azimuth, elevation)
    q = points @ R.T
    dist = 1.05 * np.linalg.norm(half, axis=1) / np.sin(fovy / 2)
    return q[..., :2] / (dist[:, None, None] - q[..., 2:3])


def _square_crop(image: np.ndarray, side: int) -> np.ndarray:
    """``image`` (H, W) cropped to the bounding box of its non-zero pixels, padded to a
    centred square and resampled (nearest) to ``side`` x ``side``."""
    rows, cols = np.nonzero(image)
    m = image[rows.min() : rows.max() + 1, cols.min() : cols.max() + 1]
    n = max(m.shape)
    sq = np.zeros((n, n), image.dtype)
    a, b = (n - m.shape[0]) // 2, (n - m.shape[1]) // 2
    sq[a : a + m.shape[0], b : b + m.shape[1]] = m
    r = ((np.arange(side) + 0.5) / side * n).astype(np.int64)
    return sq[r][:, r]


@functools.lru_cache(maxsize=8)
def _pixel_centres(G: int) -> np.ndarray:
    """(G,) coordinates of the pixel centres along a side of a unit square of G pixels."""
    g = (np.arange(G) + 0.5) / G
    g.flags.writeable = False
    return g


def _scores(
    silhouette: np.ndarray,
    parts: np.ndarray,
    azimuth: float,
    elevation: float,
    half: np.ndarray,
    fovy: float,
) -> tuple[np.ndarray, np.ndarray]:
    """(score, silhouette IoU), each (B,), of B boxes ``half`` (B, 3) in one view against
    the square-cropped silhouette and movable-part pixels (G, G) bool."""
    G = silhouette.shape[0]
    g = _pixel_centres(G)
    p = _project(_CORNERS[None] * half[:, None, :], azimuth, elevation, half, fovy)  # (B, 8, 2)
    lo, hi = p.min(axis=1), p.max(axis=1)
    side = (hi - lo).max(axis=1)
    lo = (lo + hi) / 2 - side[:, None] / 2
    # the raster's pixel centres: column u and row v, the same for every row / column
    pu = (lo[:, 0, None] + g[None] * side[:, None])[:, None]  # (B, 1, G)
    pv = (lo[:, 1, None] + g[None] * side[:, None])[:, None]
    quad = p[:, _FACE_CORNERS]  # (B, 4 faces, 4 corners, 2), each face convex
    pos = np.ones((len(p), 4, G, G), bool)
    neg = pos.copy()
    for i in range(4):  # a pixel centre is inside a face when on one side of all its edges
        a, b = quad[:, :, i, :, None], quad[:, :, (i + 1) % 4, :, None]
        # the edge's cross product with the pixel centre, (b - a) x (p - a), is a term of
        # the row less a term of the column: compared, not subtracted, on the raster
        rows = (b[:, :, 0] - a[:, :, 0]) * (pv - a[:, :, 1])  # (B, 4, G)
        cols = (b[:, :, 1] - a[:, :, 1]) * (pu - a[:, :, 0])
        pos &= rows[..., :, None] >= cols[..., None, :]
        neg &= rows[..., :, None] <= cols[..., None, :]
    inside = pos | neg  # (B, 4, G, G)
    box = inside.any(axis=1)
    inter = (box & silhouette).sum(axis=(1, 2))
    iou = inter / np.maximum(box.sum(axis=(1, 2)) + silhouette.sum() - inter, 1)
    if parts.any():
        contained = (inside[:, 0] & parts).sum(axis=(1, 2)) / parts.sum()
    else:
        contained = np.ones(len(half))
    return iou + CONTAINMENT_WEIGHT * contained, iou


@dataclass(frozen=True)
class EdgeMap:
    """The photo's intensity gradient (``gx``, ``gy``: along columns and rows, in units of
    its mean magnitude inside the silhouette) on a square crop around the silhouette:
    photo pixel (col, row) ``p`` is crop pixel ``(p - origin) * scale``; ``inner``: the
    crop pixels at least ``EDGE_INSET`` inside the silhouette."""

    gx: np.ndarray
    gy: np.ndarray
    inner: np.ndarray
    origin: np.ndarray
    scale: float


def edge_map(image: np.ndarray, silhouette: np.ndarray) -> EdgeMap | None:
    """The :class:`EdgeMap` of a photo (H, W, 3 or 4, or H, W) whose object covers
    ``silhouette`` (H, W) bool; None when the shapes differ or nothing inside the
    silhouette has a gradient."""
    image = np.asarray(image)
    sil = np.asarray(silhouette, bool)
    if image.shape[:2] != sil.shape or not sil.any():
        return None
    rows, cols = np.nonzero(sil)
    side = (1.0 + 2 * EDGE_PAD) * (max(np.ptp(rows), np.ptp(cols)) + 1)
    origin = (
        np.array([(cols.min() + cols.max() + 1) / 2, (rows.min() + rows.max() + 1) / 2]) - side / 2
    )
    scale = EDGE_SIDE / side
    # only the photo's window round the crop is read (a large photo's grey conversion
    # costs more than the rest); crop pixel centres (i + 0.5) read from it bilinearly, the
    # silhouette nearest
    c0, r0 = np.maximum(np.floor(origin).astype(int) - 1, 0)
    c1 = min(int(np.ceil(origin[0] + side)) + 2, sil.shape[1])
    r1 = min(int(np.ceil(origin[1] + side)) + 2, sil.shape[0])
    window = image[r0:r1, c0:c1]
    grey = window[..., :3].astype(float).mean(axis=-1) if window.ndim == 3 else window.astype(float)
    at = (np.arange(EDGE_SIDE) + 0.5) / scale
    cc, rr = np.meshgrid(origin[0] + at - 0.5 - c0, origin[1] + at - 0.5 - r0)
    crop = ndimage.map_coordinates(grey, [rr, cc], order=1, mode="nearest")
    inside = (
        ndimage.map_coordinates(sil[r0:r1, c0:c1].astype(float), [rr, cc], order=0, cval=0.0) > 0.5
    )
    smooth = ndimage.gaussian_filter(crop / 255.0, EDGE_SIGMA)
    gx, gy = ndimage.sobel(smooth, axis=1), ndimage.sobel(smooth, axis=0)
    inner = ndimage.binary_erosion(inside, iterations=EDGE_INSET)
    if not inner.any():
        return None
    norm = float(np.hypot(gx, gy)[inner].mean())
    if norm <= 1e-9:
        return None
    return EdgeMap(gx / norm, gy / norm, inner, origin, float(scale))


def edge_score(camera: BoxCamera, edges: EdgeMap) -> float:
    """How strongly the photo shows, where ``camera`` puts it, the box's vertical edge
    between its front and the side the camera sees: the mean gradient across that edge
    (``EdgeMap`` units) at ``EDGE_SAMPLES`` points along its middle, 0 where a point is
    not inside the silhouette. Two faces of a box are lit differently, so that edge shows
    in a photo where the silhouette cannot place it: a tall narrow box seen from 45
    degrees has nearly the silhouette of a deeper one seen from 25. (The edge between
    the front and the top is no help: a worktop's overhang and a drawer's top edge look
    alike, and with it the fitted elevations on the real dev split got worse.)"""
    hx, hy, hz = camera.half_extents
    s = 1.0 if camera.azimuth >= 0 else -1.0  # the side the camera sees
    t = np.linspace(0.15, 0.85, EDGE_SAMPLES)[:, None]
    a, b = np.array([hx, s * hy, -hz]), np.array([hx, s * hy, hz])
    px = (camera.to_pixels(a + t * (b - a)) - edges.origin) * edges.scale
    d = px[-1] - px[0]
    length = float(np.linalg.norm(d))
    if length < 1.0:
        return 0.0
    normal = np.array([-d[1], d[0]]) / length
    c = np.clip(np.floor(px).astype(np.int64), 0, edges.gx.shape[0] - 1)
    rows, cols = c[:, 1], c[:, 0]
    across = np.abs(edges.gx[rows, cols] * normal[0] + edges.gy[rows, cols] * normal[1])
    return float(np.where(edges.inner[rows, cols], across, 0.0).mean())


def fit_box_camera(
    mask: np.ndarray,
    movable_ids: list[int] | tuple[int, ...],
    depth: float | Sequence[float] | None = None,
    fovy: float = FOVY,
    edges: EdgeMap | None = None,
) -> BoxCamera:
    """The box and camera that best explain a part mask (H, W) (module docstring):
    ``movable_ids`` are the mask ids of the parts on the front; ``depth`` (the box's
    depth over its width) is fitted too when None. Given several depths, each is fitted
    and of the fits within ``DEPTH_TIE_IOU`` of the highest silhouette IoU the deepest is
    returned (module docstring). With the photo's ``edges`` (:func:`edge_map`), when the
    first fit explains the silhouette as a box (IoU at least ``BOX_IOU``), a second
    refinement also scores where the box's front/side edge falls on the photo's
    (:func:`edge_score`, ``EDGE_WEIGHT``); its fit is returned unless its silhouette IoU
    is more than ``EDGE_IOU_SLACK`` below the first's. Raises ValueError for an empty
    mask."""
    if depth is not None and np.ndim(depth) > 0:
        fits = [fit_box_camera(mask, movable_ids, float(d), fovy, edges) for d in np.unique(depth)]
        best = max(f.iou for f in fits)
        return max((f for f in fits if f.iou >= best - DEPTH_TIE_IOU), key=lambda f: f.depth)
    mask = np.asarray(mask)
    sil = mask > 0
    if not sil.any():
        raise ValueError("the part mask is empty (all background)")
    labelled = np.where(sil, 1 + np.isin(mask, list(movable_ids)), 0)
    rasters = {G: (_square_crop(sil, G), _square_crop(labelled, G) == 2) for G in FIT_RASTERS}

    log_d = (
        np.array([np.log(depth)]) if depth is not None else np.linspace(*np.log(DEPTH_RANGE), 10)
    )
    log_h = np.linspace(*np.log(HEIGHT_RANGE), 13)
    dd, hh = (a.ravel() for a in np.meshgrid(log_d, log_h, indexing="ij"))
    half = np.stack([np.exp(dd) / 2, np.full(len(dd), 0.5), np.exp(hh) / 2], axis=1)
    rows, cols = np.nonzero(sil)
    centre = ((cols.min() + cols.max() + 1) / 2, (rows.min() + rows.max() + 1) / 2)
    side = float(max(np.ptp(rows), np.ptp(cols)) + 1)

    def camera(x: np.ndarray, iou: float) -> BoxCamera:
        return BoxCamera(
            azimuth=float(x[0]),
            elevation=float(x[1]),
            depth=float(np.exp(x[2])),
            height=float(np.exp(x[3])),
            fovy=float(fovy),
            iou=iou,
            pixel_centre=centre,
            pixel_side=side,
        )

    def edge_term(x: np.ndarray) -> float:
        assert edges is not None
        return EDGE_WEIGHT * min(edge_score(camera(x, 0.0), edges), EDGE_CAP) / EDGE_CAP

    coarse = []
    S, P = rasters[FIT_RASTERS[0]]
    for az in np.radians(AZIMUTHS_DEG):
        for el in np.radians(ELEVATIONS_DEG):
            score, _ = _scores(S, P, az, el, half, fovy)
            for i in np.argsort(-score)[:3]:
                coarse.append((float(score[i]), np.array([az, el, dd[i], hh[i]])))
    coarse.sort(key=lambda c: -c[0])

    S, P = rasters[FIT_RASTERS[1]]

    seen: dict[tuple[float, ...], tuple[float, float]] = {}  # the search revisits points

    def evaluate(x: np.ndarray, edged: bool) -> tuple[float, float]:
        key = (*x.tolist(), float(edged))
        if key not in seen:
            h = np.array([[np.exp(x[2]) / 2, 0.5, np.exp(x[3]) / 2]])
            score, iou = _scores(S, P, x[0], x[1], h, fovy)
            seen[key] = (float(score[0]) + (edge_term(x) if edged else 0.0), float(iou[0]))
        return seen[key]

    def refine(edged: bool) -> np.ndarray:
        best_x, best_score = coarse[0][1], -np.inf
        for _, x0 in coarse[:REFINE_STARTS]:
            x = x0.copy()
            score = evaluate(x, edged)[0]
            steps = np.array(
                [np.radians(5), np.radians(5), 0.0 if depth is not None else 0.125, 0.125]
            )
            for _ in range(3):  # coordinate search, the steps halved each round
                improved = True
                while improved:
                    improved = False
                    for k in np.flatnonzero(steps):
                        for sign in (-1.0, 1.0):
                            y = x.copy()
                            y[k] += sign * steps[k]
                            y[1] = np.clip(y[1], 0.0, np.radians(60.0))
                            s = evaluate(y, edged)[0]
                            if s > score + 1e-9:
                                x, score, improved = y, s, True
                steps = steps / 2
            if score > best_score:
                best_x, best_score = x, score
        return best_x

    x = refine(edged=False)
    iou = evaluate(x, False)[1]
    if edges is not None and iou >= BOX_IOU:
        x_edged = refine(edged=True)
        iou_edged = evaluate(x_edged, False)[1]
        if iou_edged >= iou - EDGE_IOU_SLACK:
            x, iou = x_edged, iou_edged
    return camera(x, iou)


def depth_ratio(occ: np.ndarray) -> float | None:
    """Depth over width (x extent over y extent, in cells) of the union of part
    occupancies (T, R, R, R); None when all are empty."""
    cells = np.argwhere(np.asarray(occ, bool).any(axis=0))
    if not len(cells):
        return None
    extent = np.ptp(cells, axis=0) + 1
    return float(extent[0] / extent[1])


def _read(image: np.ndarray, camera: BoxCamera, points: np.ndarray, outside) -> np.ndarray:
    """``image`` (H, W: the mask or the silhouette) at the pixels box-frame ``points``
    (N, 3) project to; ``outside`` where they fall out of the image."""
    H, W = image.shape
    px = np.floor(camera.to_pixels(points)).astype(np.int64)
    ok = (px[:, 0] >= 0) & (px[:, 0] < W) & (px[:, 1] >= 0) & (px[:, 1] < H)
    out = np.full(len(points), outside, image.dtype)
    out[ok] = image[px[ok, 1], px[ok, 0]]
    return out


def layout_from_mask(
    occ: np.ndarray,
    mask: np.ndarray,
    slots: list[int],
    fovy: float = FOVY,
    fit_depth: bool = True,
    depths: Sequence[float] | None = None,
    image: np.ndarray | None = None,
) -> tuple[np.ndarray, BoxCamera] | None:
    """Part occupancies (T, R, R, R) rebuilt from a box and camera fitted to the part
    mask (module docstring), and that fit; None when the sample is empty, the mask shows
    no movable part or the fit's silhouette IoU is below ``MIN_FIT_IOU``. ``slots`` are
    the slots the mask shows (slot k <-> mask id k + 1; ids beyond the grids' slots count
    as the base). The box's depth over width is the sample's or one of ``depths`` (the
    other stage-1 candidates'), whichever explains the silhouette best (with
    ``fit_depth``, the freely fitted one where the camera looks down on the top and that
    fits the silhouette clearly better: module docstring); each movable part keeps its
    depth in the sample
    (scaled with the box; the median of the others', or ``CARVE_DEPTH`` cells, for a
    part the sample left empty). ``image``: the photo, for the fit's edge term
    (``fit_box_camera``)."""
    occ = np.asarray(occ, bool)
    mask = np.asarray(mask)
    T, R = occ.shape[0], occ.shape[1]
    union = occ.any(axis=0)
    movable = sorted(k for k in slots if 1 <= k < T)
    if not union.any() or not movable:
        return None
    cells = np.argwhere(union)
    extent = np.ptp(cells, axis=0) + 1
    ids = [k + 1 for k in movable]
    edges = None if image is None else edge_map(image, mask > 0)  # one per photo
    camera = fit_box_camera(
        mask, ids, depth=[depth_ratio(occ), *(depths or [])], fovy=fovy, edges=edges
    )
    if fit_depth and camera.elevation >= DEPTH_FREE_ELEVATION:
        free = fit_box_camera(mask, ids, fovy=fovy, edges=edges)
        if (
            free.iou - camera.iou > DEPTH_FREE_GAIN
            and free.elevation >= DEPTH_FREE_ELEVATION
            and abs(free.azimuth - camera.azimuth) <= DEPTH_FREE_TURN
        ):
            camera = free
    if camera.iou < MIN_FIT_IOU:
        return None

    dims = np.array([camera.depth, 1.0, camera.height])
    scale = R / dims.max()  # cells per box unit
    n = np.clip(np.round(dims * scale).astype(np.int64), 1, R)
    start = (R - n) // 2
    axes = [(np.arange(R) + 0.5 - (start[a] + n[a] / 2)) / scale for a in range(3)]
    inside = [(np.arange(R) >= start[a]) & (np.arange(R) < start[a] + n[a]) for a in range(3)]

    # the front face's cells, labelled with the slot whose mask pixels their centres hit
    Y, Z = (
        g.ravel()
        for g in np.meshgrid(np.flatnonzero(inside[1]), np.flatnonzero(inside[2]), indexing="ij")
    )
    pts = np.stack([np.full(len(Y), camera.depth / 2), axes[1][Y], axes[2][Z]], axis=1)
    ids = _read(mask, camera, pts, 0).astype(np.int64) - 1
    label = np.zeros((R, R), np.int64)  # (y, z) -> slot on the front, 0 the base
    label[Y, Z] = np.where(np.isin(ids, movable), ids, 0)
    pix = camera.to_pixels(pts)
    for k in movable:  # a part too small to hit a cell centre takes the cell under its centroid
        rows, cols = np.nonzero(mask == k + 1)
        if (label == k).any() or len(rows) == 0:
            continue
        nearest = int(np.argmin(np.hypot(pix[:, 0] - cols.mean(), pix[:, 1] - rows.mean())))
        label[Y[nearest], Z[nearest]] = k

    drawn = {k: int(np.ptp(np.argwhere(occ[k])[:, 0])) + 1 for k in movable if occ[k].any()}
    fallback = int(np.median(list(drawn.values()))) if drawn else CARVE_DEPTH
    cap = max(1, int(MAX_DEPTH_SHARE * n[0]))
    front = int(start[0] + n[0] - 1)

    box = inside[0][:, None, None] & inside[1][None, :, None] & inside[2][None, None, :]
    out = np.zeros_like(occ)
    base = box.copy()
    # carved where the camera sees background through the box
    idx = np.argwhere(box)
    centres = np.stack([axes[0][idx[:, 0]], axes[1][idx[:, 1]], axes[2][idx[:, 2]]], 1)
    sil = ndimage.binary_dilation(mask > 0, iterations=SILHOUETTE_MARGIN)
    # a cell projecting out of the photo is kept: a photo that cuts the object off says
    # nothing about what it cuts
    keep = _read(sil, camera, centres, True)
    if camera.iou < BOX_IOU:  # not quite a box (module docstring): a cell also needs its
        # mirror image across the middle (furniture is mostly left-right symmetric) seen in
        # the silhouette, or to lie in the sample (a one-sided pedestal)
        lo = cells.min(axis=0)
        grown = ndimage.binary_dilation(union, iterations=SAMPLE_MARGIN)
        src = np.clip(np.floor(lo + (idx + 0.5 - start) / n * extent).astype(np.int64), 0, R - 1)
        mirrored = _read(sil, camera, centres * np.array([1.0, -1.0, 1.0]), True)
        keep &= mirrored | grown[tuple(src.T)]
    base[tuple(idx[~keep].T)] = False

    for k in movable:
        face = label == k
        if not face.any():
            continue
        d = min(max(1, round(drawn.get(k, fallback) / extent[0] * n[0])), cap)
        part = np.zeros((R, R, R), bool)
        part[front - d + 1 : front + 1] = face[None]
        out[k] = part
        base &= ~part
        if d <= PANEL_SHARE * n[0]:  # a door: a cavity behind it, inside the base's walls
            inner = ndimage.binary_erosion(face)
            back = int(start[0]) + 1
            if front - d >= back:
                base[back : front - d + 1] &= ~inner[None]
    out[0] = base
    return out, camera

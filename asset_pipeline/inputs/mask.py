"""The part mask of an input item (docs/input-format.md, "Mask"): reading, its rules, and
whether it belongs to its photo (its foreground against the photo's silhouette, its part
boundaries against the photo's edges).
"""

from __future__ import annotations

import logging
from pathlib import Path

import numpy as np
from scipy import ndimage

from asset_pipeline.inputs.errors import InputError
from asset_pipeline.inputs.photo import (
    ALPHA_FOREGROUND,
    estimate_silhouette,
    grid_stride,
    open_image,
)

log = logging.getLogger(__name__)

#: Largest part id a mask may hold: ids are slot + 1 and there are at most 16 slots
#: (docs/dataset.md, ``max_parts``), so ids run 0 (background), 1 (base), 2..16.
MAX_PART_ID = 16

#: A part mask whose foreground (ids > 0) overlaps the photo's silhouette with an
#: intersection-over-union below this is refused as the mask of another photo. The
#: bundled examples match their own photo's estimated silhouette with IoU >= 0.82 even
#: after JPEG compression at quality 40 and added noise, and a mask is expected to
#: cover the whole object; 0.5 refuses a mask of a different framing, size or
#: position while leaving room for shadows and sloppy edges (a refusal has no override).
MASK_MIN_IOU = 0.5


def read_mask(path: str | Path, size: tuple[int, int] | None = None) -> np.ndarray:
    """Decode and check a part mask; returns (H, W) uint8 ids.

    ``size`` is the photo's (width, height); the mask must match it. Accepted
    encodings: 8-bit grey (``L``), palette (``P``: the palette indices are the ids),
    grey with alpha (alpha ignored), and RGB/RGBA whose three colour channels are
    equal (a grey image saved as colour). See :func:`check_mask` for the id rules.
    """
    path = Path(path)
    img = open_image(path, "mask")
    if size is not None and img.size != tuple(size):
        raise InputError(
            f"{path}: mask is {img.size[0]}x{img.size[1]} but the image is {size[0]}x{size[1]}; "
            "they must be the same size"
        )
    if img.mode in ("L", "P"):
        ids = np.asarray(img)
    elif img.mode == "LA":
        ids = np.asarray(img)[..., 0]
    elif img.mode in ("RGB", "RGBA"):
        a = np.asarray(img)
        if not (np.array_equal(a[..., 0], a[..., 1]) and np.array_equal(a[..., 0], a[..., 2])):
            raise InputError(
                f"{path}: mask has colour channels that differ; a mask must be a single-channel "
                "8-bit image of part ids (0 background, 1 base, 2.. movable parts)"
            )
        ids = a[..., 0]
    elif img.mode in ("I", "I;16", "I;16B", "I;16L"):
        a = np.asarray(img).astype(np.int64)
        if a.min() < 0 or a.max() > 255:
            raise InputError(
                f"{path}: 16-bit mask holds values outside 0..255; save it as 8-bit ids"
            )
        ids = a
    elif img.mode == "1":
        raise InputError(
            f"{path}: mask is 1-bit; part ids need an 8-bit single-channel image "
            "(0 background, 1 base, 2.. movable parts)"
        )
    else:
        raise InputError(f"{path}: mask mode {img.mode} is not supported; save an 8-bit grey PNG")
    ids = np.ascontiguousarray(ids, dtype=np.uint8)
    check_mask(ids, str(path))
    return ids


def check_mask(ids: np.ndarray, source: str = "<mask>") -> None:
    """Raise InputError unless ``ids`` is a valid (H, W) part-id mask.

    Rules: every id is within 0..MAX_PART_ID; some pixel has an id above 0 (the mask
    is not empty); the base (id 1) is present; the ids present above 0 are
    consecutive (1..K, no gaps), so the mask shows K parts in object order.
    """
    present = np.unique(ids)
    too_big = present[present > MAX_PART_ID]
    if too_big.size:
        raise InputError(
            f"{source}: mask holds part ids {too_big.tolist()[:8]} above {MAX_PART_ID} "
            f"(at most {MAX_PART_ID} parts: 0 background, 1 base, 2..{MAX_PART_ID} movable parts); "
            "is this a colour image or an anti-aliased mask?"
        )
    fg = [int(v) for v in present if v > 0]
    if not fg:
        raise InputError(
            f"{source}: mask is empty (no pixel has a part id > 0); paint the base as 1 and the "
            "movable parts as 2, 3, ..., or delete the mask (it is optional)"
        )
    if 1 not in fg:
        raise InputError(
            f"{source}: mask has part ids {fg} but no base (id 1); the base must be visible"
        )
    missing = sorted(set(range(1, max(fg) + 1)) - set(fg))
    if missing:
        raise InputError(
            f"{source}: mask part ids must be consecutive 1..K; ids {missing} are missing "
            f"(present: {fg}); renumber the movable parts 2, 3, ..."
        )


# --------------------------------------------------------------------------- mask vs photo


def check_mask_matches_photo(
    mask: np.ndarray,
    image: np.ndarray,
    alpha: np.ndarray | None,
    source: str = "<mask>",
) -> None:
    """Refuse a part mask that does not fit the photo's silhouette (another photo's mask).

    ``mask``: (H, W) uint8 part ids; ``image``: (H, W, 3) uint8 RGB; ``alpha``: (H, W)
    uint8 or None. The silhouette is ``alpha >= ALPHA_FOREGROUND`` when there is an
    alpha channel, else :func:`estimate_silhouette` (nothing is checked when it
    cannot be estimated). Raises InputError when the IoU of the mask's foreground
    (ids > 0) and the silhouette is below MASK_MIN_IOU. Both are compared on a grid
    of at most SILHOUETTE_GRID px a side, so this costs a few ms at any photo size.
    """
    h, w = mask.shape
    stride = grid_stride(h, w)
    if alpha is not None:
        silhouette = alpha[::stride, ::stride] >= ALPHA_FOREGROUND
        what = "from its alpha channel"
    else:
        estimated = estimate_silhouette(image, stride)
        if estimated is None:
            return
        silhouette = estimated
        what = "estimated against its plain background"
    parts = mask[::stride, ::stride] > 0
    union = np.count_nonzero(parts | silhouette)
    iou = np.count_nonzero(parts & silhouette) / union if union else 1.0
    if iou < MASK_MIN_IOU:
        cover = 100.0 * np.count_nonzero(parts) / parts.size
        obj = 100.0 * np.count_nonzero(silhouette) / silhouette.size
        raise InputError(
            f"{source}: the mask does not match the photo: its parts cover {cover:.0f}% of the "
            f"image where the photo's object covers {obj:.0f}% (IoU {iou:.2f} with the photo's "
            f"silhouette, {what}; at least {MASK_MIN_IOU} is needed); is it the mask of "
            "another photo? Use the photo's own mask or delete it (it is optional)"
        )


#: The mask's inner part boundaries should run along edges of the photo: the mean edge
#: strength on them, over the mean inside the object (:func:`mask_edge_support`). A
#: photo's own mask scores 1.4-6.7 on the bundled examples, another photo's mask 0.0-6.0
#: (29 of 56 swaps below 1.0); but on renders of real artist-made objects (wood grain,
#: a drawer front in its frame's colour, a dark glass door in a dark frame) a photo's
#: own mask scores down to 0.18. So a low score alone never refuses a mask: below
#: MASK_EDGE_WARN the item carries a warning.
MASK_EDGE_WARN = 1.0
#: A mask is refused as another photo's only on strong evidence: its part boundaries
#: lie where the photo has next to no edges (below MASK_EDGE_REFUSE) *and* so does its
#: outline, the boundary between object and background (:func:`mask_outline_support`
#: below MASK_OUTLINE_REFUSE). A photo's own mask follows the object's outline (1.6-41
#: on the bundled examples: the object stands out from its background even where its
#: parts do not stand out from each other); a washing machine's mask on the dishwasher's
#: photo scores 0.00 on its part boundaries and 0.80 on its outline.
MASK_EDGE_REFUSE = 0.2
MASK_OUTLINE_REFUSE = 1.0
#: Edge support is measured on a grid of at most this many pixels a side.
EDGE_GRID = 512


def _edge_supports(mask: np.ndarray, image: np.ndarray) -> tuple[float | None, float | None]:
    """(part-boundary support, outline support) of :func:`mask_edge_support` and
    :func:`mask_outline_support`, from one gradient image."""
    stride = max(1, -(-max(mask.shape) // EDGE_GRID))
    m = mask[::stride, ::stride]
    grey = image[::stride, ::stride].astype(np.float32).mean(axis=2)
    grad = np.hypot(ndimage.sobel(grey, 1), ndimage.sobel(grey, 0))
    grad = ndimage.maximum_filter(grad, size=5)
    inner = np.zeros(m.shape, bool)
    outline = np.zeros(m.shape, bool)
    for dy, dx in ((0, 1), (1, 0)):
        a, b = m[: m.shape[0] - dy, : m.shape[1] - dx], m[dy:, dx:]
        inner[: m.shape[0] - dy, : m.shape[1] - dx] |= (a != b) & (a > 0) & (b > 0)
        outline[: m.shape[0] - dy, : m.shape[1] - dx] |= (a > 0) != (b > 0)
    inside = ndimage.binary_erosion(m > 0, iterations=3)
    if not inside.any():
        return None, None
    mean_inside = float(grad[inside].mean())
    if mean_inside <= 0:
        return None, None
    boundary = ndimage.binary_dilation(inner) & inside
    parts = float(grad[boundary].mean()) / mean_inside if boundary.any() else None
    edge = float(grad[outline].mean()) / mean_inside if outline.any() else None
    return parts, edge


def mask_edge_support(mask: np.ndarray, image: np.ndarray) -> float | None:
    """How strongly the photo has edges where the mask puts boundaries between parts.

    ``mask``: (H, W) uint8 part ids; ``image``: (H, W, 3) uint8 RGB. Returns the mean
    gradient magnitude (5 px max-filtered, so a boundary 1-2 px off still counts) on the
    boundaries between two different non-zero ids, divided by its mean over the mask's
    foreground eroded by 3 px; None when the mask has no inner boundary. Dimensionless:
    1 means the boundaries are no stronger than the object's average texture.
    """
    return _edge_supports(mask, image)[0]


def mask_outline_support(mask: np.ndarray, image: np.ndarray) -> float | None:
    """How strongly the photo has edges along the mask's outline (its pixels next to the
    background, id 0), measured as :func:`mask_edge_support`; None when the mask has no
    outline inside the image or no inside."""
    return _edge_supports(mask, image)[1]


def check_mask_edges(mask: np.ndarray, image: np.ndarray, source: str = "<mask>") -> list[str]:
    """Warnings about a mask whose part boundaries do not follow the photo's edges;
    InputError when neither they nor its outline do (see :data:`MASK_EDGE_REFUSE`).

    ``mask``: (H, W) uint8 part ids; ``image``: (H, W, 3) uint8 RGB.
    """
    parts, outline = _edge_supports(mask, image)
    if parts is None or parts >= MASK_EDGE_WARN:
        return []
    if parts < MASK_EDGE_REFUSE and outline is not None and outline < MASK_OUTLINE_REFUSE:
        raise InputError(
            f"{source}: neither the mask's outline nor the boundaries between its parts follow "
            f"edges in the photo (outline support {outline:.2f}, below {MASK_OUTLINE_REFUSE}; "
            f"part-boundary support {parts:.2f}, below {MASK_EDGE_REFUSE}): it looks like the "
            "mask of another photo. Use the photo's own mask or delete it (it is optional)"
        )
    return [
        f"{source}: the boundaries between the mask's parts do not follow edges in the photo "
        f"(edge support {parts:.2f}, a photo's own mask usually scores above {MASK_EDGE_WARN}); "
        "is it the mask of another photo?"
    ]

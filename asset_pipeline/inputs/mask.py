"""The part mask of an input item (docs/input-format.md, "Mask"): reading, cleaning (as
people and tools make masks: :func:`clean_mask`), its rules, and whether it belongs to
its photo (its foreground against the photo's silhouette, its part boundaries and
outline against the photo's edges).
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
#: Below MASK_MIN_IOU a mask is still the photo's own when the photo's estimated
#: silhouette takes in more than the object: a cast shadow on the floor under a table,
#: the floor seen between thin legs (the silhouette is what differs from the background
#: colour, and a shadow does). Such a mask lies inside the silhouette (at least
#: MASK_CONTAINED of its pixels) and its whole outline runs along edges of the photo
#: (:func:`mask_outline_coverage` at least MASK_OUTLINE_COVERED), while another photo's
#: mask that happens to fall inside the object crosses flat regions of it. Chosen on the
#: bundled examples, the parser's procedural val renders and dev half A of the real
#: renders: the 8 own masks there with IoU 0.25-0.5 and containment at least 0.95
#: (thin-legged desks) cover 0.95-1.00 of their outline, the 94 masks of other photos
#: in that range (among 4,277 swaps) at most 0.74. Below MASK_FLOOR_IOU a mask is
#: refused whatever its outline.
MASK_CONTAINED = 0.95
MASK_OUTLINE_COVERED = 0.85
MASK_FLOOR_IOU = 0.25


def mask_png(ids: np.ndarray) -> bytes:
    """Part ids (H, W) encoded as a mask file: an 8-bit grey PNG (what :func:`read_mask`
    reads)."""
    from io import BytesIO

    from PIL import Image

    buf = BytesIO()
    Image.fromarray(np.ascontiguousarray(ids, dtype=np.uint8), "L").save(buf, format="PNG")
    return buf.getvalue()


def write_mask(ids: np.ndarray, path: str | Path) -> Path:
    """Write part ids (H, W) as a mask file, atomically (the one writer of the format)."""
    from generator.atomic_files import atomic_write_bytes

    atomic_write_bytes(Path(path), mask_png(ids))
    return Path(path)


def read_mask(
    path: str | Path,
    size: tuple[int, int] | None = None,
    warnings: list[str] | None = None,
    renumbered: dict[int, int] | None = None,
) -> np.ndarray:
    """Decode, clean and check a part mask; returns (H, W) uint8 ids.

    ``size`` is the photo's (width, height); the mask must match it. Accepted
    encodings: 8-bit grey (``L``), palette (``P``: the palette indices are the ids),
    grey with alpha (alpha ignored), and RGB/RGBA whose three colour channels are
    equal (a grey image saved as colour). The ids are cleaned (:func:`clean_mask`:
    in-between values, specks and small holes, skipped ids renumbered), each change
    noted in ``warnings`` (naming the file), then checked (:func:`check_mask`). The ids
    that changed go into ``renumbered`` (old -> new), for what refers to them (the hints'
    ``parts``).
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
    ids, notes, mapping = clean_mask(np.asarray(ids), str(path))
    if renumbered is not None:
        renumbered.update(mapping)
    for note in notes:
        log.info("%s", note)
    if warnings is not None:
        warnings.extend(notes)
    check_mask(ids, str(path))
    return ids


#: Cleaning (:func:`clean_mask`). A component of an id smaller than this share of the
#: mask's pixels (at least MIN_SPECK_PIXELS) is a speck ...
SPECK_SHARE = 0.0005
MIN_SPECK_PIXELS = 4
#: A component of at most this many pixels is a speck wherever it lies (the in-between
#: values of an anti-aliased diagonal edge); a larger speck must be isolated: in one id.
TINY_PIXELS = 2
#: ... a region of background enclosed by the object and smaller than this share is a
#: hole ...
HOLE_SHARE = 0.001
#: ... and more than this share of pixels holding values above MAX_PART_ID, or more
#: than NOISE_SHARE of the object's pixels to reassign, is not a mask to clean but a
#: picture (a photo, a visualisation) saved as one.
INVALID_SHARE = 0.02
NOISE_SHARE = 0.25
#: Cleaning that changes fewer than this share of the object's pixels (and no value
#: above MAX_PART_ID) is logged, not a warning of the item.
NOTE_SHARE = 0.0005
_FOUR = ndimage.generate_binary_structure(2, 1)
_SQUARE = np.ones((3, 3), bool)


def _isolated(ids: np.ndarray, labels: np.ndarray, count: int) -> np.ndarray:
    """(count + 1,) bool: whether each labelled component is surrounded by one id only
    (its 4-neighbours outside it all hold the same other value)."""
    ring = ndimage.binary_dilation(labels > 0, _FOUR) & (labels == 0)
    near = ndimage.grey_dilation(labels, footprint=_FOUR)  # a component next to each ring px
    lo = np.full(count + 1, 1 << 30, np.int64)
    hi = np.full(count + 1, -1, np.int64)
    np.minimum.at(lo, near[ring], ids[ring])
    np.maximum.at(hi, near[ring], ids[ring])
    return lo == hi


def _noise(ids: np.ndarray) -> tuple[np.ndarray, dict[str, int]]:
    """The pixels to reassign (see :func:`clean_mask`) and how many of each kind."""
    n = ids.size
    speck = max(MIN_SPECK_PIXELS, int(np.ceil(SPECK_SHARE * n)))
    hole = max(MIN_SPECK_PIXELS, int(np.ceil(HOLE_SHARE * n)))
    invalid = ids > MAX_PART_ID
    noise = invalid.copy()
    kinds = {"invalid": int(invalid.sum()), "specks": 0, "holes": 0}
    for k in (int(v) for v in np.unique(ids) if v <= MAX_PART_ID):
        whole = ids == k
        if k == 0:  # enclosed background: a hole when small
            labels, count = ndimage.label(whole, _FOUR)
            sizes = np.bincount(labels.ravel(), minlength=count + 1)
            bad = sizes < hole
            bad[np.unique(np.r_[labels[0], labels[-1], labels[:, 0], labels[:, -1]])] = False
            bad[0] = False
            marked = bad[labels]
            kinds["holes"] += int(marked.sum())
            noise |= marked
            continue
        # the id's pixels and a 1 px ring round them (its neighbours), cut out
        rows, cols = np.flatnonzero(whole.any(axis=1)), np.flatnonzero(whole.any(axis=0))
        box = np.s_[max(rows[0] - 1, 0) : rows[-1] + 2, max(cols[0] - 1, 0) : cols[-1] + 2]
        region = whole[box]
        labels, count = ndimage.label(region, _FOUR)
        sizes = np.bincount(labels.ravel(), minlength=count + 1)
        bad = np.zeros(count + 1, bool)
        core = ndimage.binary_erosion(region, _SQUARE, iterations=2)
        if k != 1 and np.count_nonzero(core) < speck:
            bad[1:] = True  # specks and lines along edges only: no part at all
        else:
            bad[1:] = sizes[1:] <= TINY_PIXELS
            if k != 1:  # a line of a movable part's id along other edges: in-between values
                thick = np.bincount(
                    labels[ndimage.binary_erosion(region, _SQUARE)], minlength=count + 1
                )
                bad[1:] |= thick[1:] == 0
            doubtful = (sizes > TINY_PIXELS) & (sizes < speck) & ~bad
            doubtful[0] = False
            if doubtful.any():
                bad |= doubtful & _isolated(ids[box], labels, count)
            bad[1 + int(np.argmax(sizes[1:]))] = False  # the part itself stays
        marked = bad[labels]
        kinds["specks"] += int(marked.sum())
        noise[box] |= marked
    return noise, kinds


def _reassign(ids: np.ndarray, noise: np.ndarray) -> np.ndarray:
    """``ids`` with each ``noise`` pixel given the most frequent id among the other
    pixels of its 5x5 neighbourhood (the nearest such pixel's id when it has none)."""
    out = ids.copy()
    rows, cols = np.nonzero(noise)
    box = np.s_[max(rows.min() - 3, 0) : rows.max() + 4, max(cols.min() - 3, 0) : cols.max() + 4]
    sub, hit = ids[box], noise[box]
    best = np.full(sub.shape, -1, np.int16)
    votes = np.zeros(sub.shape, np.float32)
    for k in np.unique(sub[~hit]):
        count = ndimage.uniform_filter(((sub == k) & ~hit).astype(np.float32), size=5)
        better = hit & (count > votes + 1e-6)
        best[better], votes[better] = k, count[better]
    left = hit & (best < 0)
    if left.any():
        _, (iy, ix) = ndimage.distance_transform_edt(noise, return_indices=True)
        full = ids[iy, ix][box]
        best[left] = full[left]
    out[box] = np.where(hit, best, sub)
    return out


def clean_mask(
    raw: np.ndarray, source: str = "<mask>"
) -> tuple[np.ndarray, list[str], dict[int, int]]:
    """Clean a mask as people and tools make them; returns (uint8 ids, notes, the ids
    renumbered: old -> new).

    Reassigned to the id most frequent around them (:func:`_reassign`): values above
    MAX_PART_ID, specks (a component of an id, 4-connected, smaller than
    :data:`SPECK_SHARE` of the pixels, or nowhere 3 px thick, as the in-between values
    of anti-aliased edges are; never an id's largest component, unless the whole id is
    that small or that thin and is not the base) and holes (background enclosed by the
    object, smaller than :data:`HOLE_SHARE`). Then ids that skip a number (a movable
    part hidden in this view) are renumbered consecutively, base first. Each change is
    a note naming ``source``. Raises InputError when the values above MAX_PART_ID are
    more than :data:`INVALID_SHARE` of the pixels or the reassigned pixels more than
    :data:`NOISE_SHARE` of the object's: a photo or a picture, not a mask.
    """
    ids = np.asarray(raw)
    notes = []
    present = np.unique(ids)
    too_big = present[present > MAX_PART_ID]
    n_big = int(np.count_nonzero(ids > MAX_PART_ID)) if too_big.size else 0
    if n_big > INVALID_SHARE * ids.size:
        raise InputError(
            f"{source}: mask holds part ids {too_big.tolist()[:8]} above {MAX_PART_ID} in "
            f"{n_big / ids.size:.0%} of its pixels (at most {MAX_PART_ID} parts: 0 background, "
            f"1 base, 2..{MAX_PART_ID} movable parts); is this a photo, a colour image or a mask "
            "saved with other values? Save a single-channel image of part ids"
        )
    noise, kinds = _noise(ids)
    movable = (ids >= 2) & (ids <= MAX_PART_ID)
    if movable.any() and not (movable & ~noise).any():
        # Every movable part would go. The in-between values of anti-aliased edges never
        # make up a mask's only movable part (between the base and the background there
        # is no id), so this is a part seen edge-on (a top-loader's lid from the front):
        # the movable id the mask shows most of stays, thin as it is.
        values, counts = np.unique(ids[movable], return_counts=True)
        k = int(values[np.argmax(counts)])
        keep = noise & (ids == k)
        kinds["specks"] -= int(keep.sum())
        noise &= ~keep
        notes.append(
            f"{source}: part {k} is a sliver of {int(counts.max())} px in this photo, too thin "
            "to tell from an edge, but the mask's only movable part: kept"
        )
    n_noise = int(noise.sum())
    if n_noise:
        obj = max(int(np.count_nonzero((ids > 0) | noise)), 1)
        if n_noise > NOISE_SHARE * obj:
            raise InputError(
                f"{source}: this is not a mask of part ids: {n_noise / obj:.0%} of its object's "
                "pixels are specks, lines one or two pixels thin or values above "
                f"{MAX_PART_ID} (a photo or a picture saved as a mask?); save a single-channel "
                "image of part ids (0 background, 1 base, 2.. movable parts)"
            )
        ids = _reassign(ids, noise)
        what = {
            "invalid": f"values above {MAX_PART_ID}",
            "specks": "specks and thin in-between edges",
            "holes": "small holes",
        }
        done = ", ".join(f"{v} px of {what[k]}" for k, v in kinds.items() if v)
        note = (
            f"{source}: mask cleaned: {done} ({n_noise / obj:.1%} of the object) given the "
            "part id around them"
        )
        if kinds["invalid"] or n_noise >= NOTE_SHARE * obj:
            notes.append(note)
        else:  # a pixel or two of an exact mask's slivers: not worth a warning
            log.debug("%s", note)
    ids = np.ascontiguousarray(ids, dtype=np.uint8)
    fg = [int(v) for v in np.unique(ids) if v > 0]
    renumbered: dict[int, int] = {}
    if fg and 1 in fg and fg != list(range(1, len(fg) + 1)):
        lut = np.zeros(256, np.uint8)
        lut[fg] = np.arange(1, len(fg) + 1)
        ids = lut[ids]
        renumbered = {old: int(lut[old]) for old in fg if lut[old] != old}
        mapping = ", ".join(f"{old} -> {new}" for old, new in renumbered.items())
        missing = sorted(set(range(1, max(fg) + 1)) - set(fg))
        notes.append(
            f"{source}: mask part ids {fg} skip {missing} (a movable part hidden in this view?); "
            f"renumbered {mapping}"
        )
    return ids, notes, renumbered


def check_mask(ids: np.ndarray, source: str = "<mask>") -> None:
    """Raise InputError unless ``ids`` is a valid (H, W) part-id mask.

    Rules: every id is within 0..MAX_PART_ID; some pixel has an id above 0 (the mask
    is not empty); the base (id 1) is present; the ids present above 0 are
    consecutive (1..K, no gaps), so the mask shows K parts in object order.
    :func:`read_mask` checks ids after :func:`clean_mask`, so of these only an empty
    mask and a missing base refuse a mask file.
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
    (ids > 0) and the silhouette is below MASK_MIN_IOU, unless the mask lies inside the
    silhouette and its outline follows the photo's edges (MASK_CONTAINED,
    MASK_OUTLINE_COVERED, MASK_FLOOR_IOU: the silhouette took in a shadow). Both are
    compared on a grid of at most SILHOUETTE_GRID px a side, so this costs a few ms at
    any photo size.
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
    inter = np.count_nonzero(parts & silhouette)
    union = np.count_nonzero(parts | silhouette)
    iou = inter / union if union else 1.0
    if iou < MASK_MIN_IOU and iou >= MASK_FLOOR_IOU:
        contained = inter / max(1, np.count_nonzero(parts))
        if contained >= MASK_CONTAINED:
            covered = mask_outline_coverage(mask, image)
            if covered is not None and covered >= MASK_OUTLINE_COVERED:
                return  # the silhouette holds a shadow or floor; the mask is the object's
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


def _edge_image(mask: np.ndarray, image: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """(mask, gradient magnitude 5 px max-filtered) on a grid of at most EDGE_GRID px."""
    stride = max(1, -(-max(mask.shape) // EDGE_GRID))
    grey = image[::stride, ::stride].astype(np.float32).mean(axis=2)
    grad = np.hypot(ndimage.sobel(grey, 1), ndimage.sobel(grey, 0))
    return mask[::stride, ::stride], ndimage.maximum_filter(grad, size=5)


def _outline(m: np.ndarray) -> np.ndarray:
    """(H, W) bool: the pixels of a part-id grid next to (right of or below) a pixel on
    the other side of the object's outline (foreground ids > 0 against background 0)."""
    fg = m > 0
    outline = np.zeros(m.shape, bool)
    for dy, dx in ((0, 1), (1, 0)):
        outline[: m.shape[0] - dy, : m.shape[1] - dx] |= (
            fg[: m.shape[0] - dy, : m.shape[1] - dx] != fg[dy:, dx:]
        )
    return outline


def _edge_supports(mask: np.ndarray, image: np.ndarray) -> tuple[float | None, float | None]:
    """(part-boundary support, outline support) of :func:`mask_edge_support` and
    :func:`mask_outline_support`, from one gradient image."""
    m, grad = _edge_image(mask, image)
    inner = np.zeros(m.shape, bool)
    for dy, dx in ((0, 1), (1, 0)):
        a, b = m[: m.shape[0] - dy, : m.shape[1] - dx], m[dy:, dx:]
        inner[: m.shape[0] - dy, : m.shape[1] - dx] |= (a != b) & (a > 0) & (b > 0)
    outline = _outline(m)
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


def mask_outline_coverage(mask: np.ndarray, image: np.ndarray) -> float | None:
    """The share of the mask's outline (its pixels next to the background, id 0) along
    which the photo has an edge: the gradient there (5 px max-filtered, as
    :func:`mask_edge_support`) at least its mean over the mask's foreground eroded by
    3 px. 1.0 when the outline follows the object's contour all round; None when the
    mask has no outline inside the image or no inside. Unlike the mean of
    :func:`mask_outline_support`, a few strong edges do not make up for long stretches
    of the outline over flat paint."""
    m, grad = _edge_image(mask, image)
    outline = _outline(m)
    inside = ndimage.binary_erosion(m > 0, iterations=3)
    if not inside.any() or not outline.any():
        return None
    mean_inside = float(grad[inside].mean())
    if mean_inside <= 0:
        return None
    return float(np.mean(grad[outline] >= mean_inside))


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

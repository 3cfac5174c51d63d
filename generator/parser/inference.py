"""Parse a photo: its category, its part mask and each movable part's motion.

    parser = PhotoParser.default()          # shipped weights, CPU, cached per process
    parsed = parser.parse(image)            # (H, W, 3) uint8 RGB [, alpha=(H, W) bool]
    parsed.category, parsed.category_confidence, parsed.mask, parsed.parts, parsed.seconds
    parser.label(image, mask)               # a given mask: category and each region's motion
    parser.merge_regions(image, regions)    # candidate regions (SAM2's) merged into parts

How (``docs/parser.md``): the photo is letterboxed to the network's size and run once to
find the object (unless a silhouette ``alpha`` is given); a square round the object
(it fills ``fill`` of the side, as in training) is resampled and run again, with its
mirror image (whose left and right doors swap back). The network's per-pixel
probabilities (background, base, movable part; a part's edge; six motions) and box votes
are mapped back onto the photo. Parts are the groups of movable pixels that vote for one
box (:func:`box_groups`; weights without a box head: the connected components of the
movable pixels off the edges); the other movable pixels join the nearest part within
reach. A part's motion is the mean of its pixels' motion probabilities; the category is
the mean of the two views' category probabilities. On a CPU without native bfloat16 the
network runs in float32 (:func:`~generator.parser.model.cpu_has_native_bf16`).
"""

from __future__ import annotations

import hashlib
import json
import logging
import threading
import time
from dataclasses import dataclass, field
from pathlib import Path

import cv2
import numpy as np
import torch
from scipy import ndimage

from generator.motions import MOTIONS
from generator.parser.data import FLIP_MOTION, MOTION_PRIOR_NAME, letterbox_matrix
from generator.parser.model import CATEGORIES, ParserNet, cpu_has_native_bf16, load_weights

log = logging.getLogger(__name__)

DEFAULT_WEIGHTS = Path(__file__).resolve().parent / "weights"
#: Shipped weights by name: "shipped" (trained on the project's procedural renders only,
#: the default) and "partnet" (fine-tuned on renders of PartNet-Mobility objects too;
#: under that data's terms, docs/parser.md).
NAMED_WEIGHTS = {
    "shipped": DEFAULT_WEIGHTS,
    "partnet": Path(__file__).resolve().parent / "weights_partnet",
}


def weights_dir(name_or_path: str | Path) -> Path:
    """The folder of shipped weights named ``name_or_path`` (NAMED_WEIGHTS), else the
    path itself."""
    return NAMED_WEIGHTS.get(str(name_or_path), Path(name_or_path))


@dataclass
class ParsedPart:
    id: int  # mask id, >= 2
    motion: str  # one of MOTIONS
    confidence: float  # 0..1: the mean probability of ``motion`` over the part's pixels
    motion_probs: dict[str, float] = field(default_factory=dict, repr=False)


@dataclass
class ParsedPhoto:
    category: str  # one of CATEGORIES
    category_confidence: float  # 0..1
    mask: np.ndarray  # (H, W) uint8: 0 background, 1 base, 2..K parts
    parts: list[ParsedPart]  # one per id >= 2, by id
    seconds: float
    category_probs: dict[str, float] = field(default_factory=dict, repr=False)
    notes: list[str] = field(default_factory=list)  # what a person should check


@dataclass
class PixelMaps:
    """The network's beliefs on the photo's pixels (H, W): ``seg`` (4, H, W): probabilities
    of background / base / movable part, then of a part's edge; ``motion`` (6, H, W)
    probabilities; ``category`` (8,); ``box`` (with a box head) on each pixel the
    distances in photo pixels to the left, top, right and bottom edges of its part's box."""

    seg: np.ndarray
    motion: np.ndarray
    category: np.ndarray
    box: np.ndarray | None = None  # (4, H, W) photo pixels to the part's box edges (l, t, r, b)


@dataclass
class RegionScores:
    """Per candidate region: ``classes`` (R, 3) mean probability of background, base and
    movable part; ``overlap`` (R, P) share of the region's pixels in each of the parse's
    P parts; ``parse`` the full parse they were measured against."""

    classes: np.ndarray
    overlap: np.ndarray
    parse: ParsedPhoto


class PhotoParser:
    """The parser around one ``ParserNet`` (eval mode)."""

    _default: PhotoParser | None = None
    _lock = threading.Lock()

    def __init__(
        self,
        model: ParserNet,
        *,
        device: str | torch.device = "cpu",
        threads: int | None = None,
        fill: float = 0.75,
        flip: bool = True,
        min_part: float = 0.03,
        reach: float = 0.04,
        edge: float = 0.35,
        grouping: BoxGrouping | None = None,
        fallback_movable: float = 0.25,
        bf16: bool | None = None,
        version: str = "parser-untrained",
        motion_counts: dict[str, dict[str, int]] | None = None,
    ) -> None:
        self.model = model.eval().to(device, memory_format=torch.channels_last)
        self.version = version  # names the weights in reports, hints and the catalog
        self.motion_prior = _motion_prior(motion_counts or {})
        self.device = torch.device(device)
        self.size = int(model.cfg.image_size)
        self.threads = threads
        self.fill = fill
        self.flip = flip
        # how movable pixels become parts (:func:`instances`)
        self.min_part, self.reach, self.edge = min_part, reach, edge
        self.grouping = grouping or BoxGrouping()
        # no part found on an object of the seven categories (each has a moving part):
        # the pixels whose movable share of the base plus movable probability is above this
        # make the parts instead (0: such an object stays without parts)
        self.fallback_movable = fallback_movable
        # bf16 autocast on a CPU that computes it natively (None: find out), else float32
        if bf16 is None:
            bf16 = cpu_has_native_bf16()
        self.bf16 = bf16 and self.device.type == "cpu"

    # ------------------------------------------------------------------ construction

    @classmethod
    def from_dir(
        cls, path: str | Path, device: str | torch.device | None = None, **kw
    ) -> PhotoParser:
        device = device or ("cuda" if torch.cuda.is_available() else "cpu")
        model, meta = load_weights(path, device)
        digest = hashlib.sha256((Path(path) / "model.safetensors").read_bytes()).hexdigest()
        kw.setdefault("version", f"parser-{meta.get('extra', {}).get('step', 0)}-{digest[:8]}")
        prior = Path(path) / MOTION_PRIOR_NAME
        if prior.is_file():
            kw.setdefault("motion_counts", json.loads(prior.read_text())["counts"])
        return cls(model, device=device, **kw)

    @classmethod
    def default(cls) -> PhotoParser:
        """The shipped weights (``generator/parser/weights``), loaded once per process."""
        with cls._lock:
            if cls._default is None:
                cls._default = cls.from_dir(DEFAULT_WEIGHTS)
            return cls._default

    # ------------------------------------------------------------------ network

    @torch.no_grad()
    def _run(
        self, square: np.ndarray
    ) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray | None]:
        """(S, S, 3) uint8 -> seg (4, S, S) (3 classes + edge), motion (6, S, S)
        probabilities, category (8,), box (4, S, S) distances in square pixels or None."""
        x = torch.from_numpy(square).to(self.device).permute(2, 0, 1).float() / 255
        batch = torch.stack([x, x.flip(-1)]) if self.flip else x[None]
        batch = batch.contiguous(memory_format=torch.channels_last)
        with torch.autocast("cpu", dtype=torch.bfloat16, enabled=self.bf16):
            out = self.model(batch)
        size = (self.size, self.size)
        seg = torch.cat(
            [
                torch.nn.functional.interpolate(out.seg.float(), size, mode="bilinear").softmax(1),
                torch.nn.functional.interpolate(
                    out.boundary.float(), size, mode="bilinear"
                ).sigmoid(),
            ],
            1,
        )
        mot = torch.nn.functional.interpolate(out.motion.float(), size, mode="bilinear").softmax(1)
        cat = out.category.float().softmax(1)
        box = None
        if out.box is not None:
            box = torch.nn.functional.interpolate(out.box.float(), size, mode="bilinear")
            box = box * self.size
        if self.flip:
            seg = (seg[0] + seg[1].flip(-1)) / 2
            mot = (mot[0] + mot[1].flip(-1)[torch.as_tensor(FLIP_MOTION)]) / 2
            cat = cat.mean(0)
            if box is not None:  # the mirror's left and right distances swap back
                box = (box[0] + box[1].flip(-1)[torch.as_tensor([2, 1, 0, 3])]) / 2
        else:
            seg, mot, cat = seg[0], mot[0], cat[0]
            box = None if box is None else box[0]
        return (
            seg.cpu().numpy(),
            mot.cpu().numpy(),
            cat.cpu().numpy(),
            None if box is None else box.cpu().numpy(),
        )

    def _warp_in(self, image: np.ndarray, M: np.ndarray) -> np.ndarray:
        return cv2.warpAffine(
            image,
            M,
            (self.size, self.size),
            flags=cv2.INTER_AREA if M[0, 0] < 1 else cv2.INTER_LINEAR,
            borderMode=cv2.BORDER_CONSTANT,
            borderValue=(127, 127, 127),
        )

    def _warp_out(
        self, maps: np.ndarray, M: np.ndarray, h: int, w: int, border: list[float]
    ) -> np.ndarray:
        """(C, S, S) maps in the square -> (C, h, w) on the photo (``M``: photo -> square)."""
        out = np.empty((maps.shape[0], h, w), np.float32)
        for c in range(maps.shape[0]):
            out[c] = cv2.warpAffine(
                maps[c],
                M,
                (w, h),
                flags=cv2.INTER_LINEAR | cv2.WARP_INVERSE_MAP,
                borderMode=cv2.BORDER_CONSTANT,
                borderValue=border[c],
            )
        return out

    def crop_matrix(self, silhouette: np.ndarray) -> np.ndarray:
        """2 x 3 affine photo -> square framing the silhouette's box (it fills ``fill``)."""
        ys, xs = np.nonzero(silhouette)
        h, w = silhouette.shape
        if len(ys) == 0:
            return letterbox_matrix(h, w, self.size)
        y0, y1, x0, x1 = ys.min(), ys.max() + 1, xs.min(), xs.max() + 1
        side = max(y1 - y0, x1 - x0, 8) / self.fill
        s = self.size / side
        cx, cy = (x0 + x1) / 2, (y0 + y1) / 2
        return np.array([[s, 0, self.size / 2 - s * cx], [0, s, self.size / 2 - s * cy]])

    def pixel_maps(self, image: np.ndarray, alpha: np.ndarray | None = None) -> PixelMaps:
        """The network's probabilities on the photo's pixels (two passes, see the module)."""
        image = _rgb(image)
        h, w = image.shape[:2]
        if alpha is None:
            M0 = letterbox_matrix(h, w, self.size)
            seg0 = self._run(self._warp_in(image, M0))[0]
            fg = self._warp_out(seg0[:1], M0, h, w, [1.0])[0] < 0.5
            alpha = _main_object(fg)
        M = self.crop_matrix(alpha)
        seg, mot, cat, box = self._run(self._warp_in(image, M))
        seg = self._warp_out(seg, M, h, w, [1.0, 0.0, 0.0, 0.0])
        mot = self._warp_out(mot, M, h, w, [1.0 / len(MOTIONS)] * len(MOTIONS))
        if box is not None:  # square pixels -> photo pixels (the crop is a pure scaling)
            box = self._warp_out(box, M, h, w, [0.0] * 4) / float(M[0, 0])
        return PixelMaps(seg, mot, cat, box)

    # ------------------------------------------------------------------ the API

    def parse(
        self, image: np.ndarray, alpha: np.ndarray | None = None, category: str | None = None
    ) -> ParsedPhoto:
        """Category, part mask (photo size) and motions of a bare photo; ``alpha`` (H, W)
        bool: the object's silhouette when known (pixels outside it are background);
        ``category``: the object's category when known (it weighs each part's motion by
        what that category's parts do in the training data, ``motion_prior``)."""
        return self._parse(image, alpha, category)[0]

    def _parse(
        self, image: np.ndarray, alpha: np.ndarray | None, category: str | None = None
    ) -> tuple[ParsedPhoto, PixelMaps]:
        t0 = time.perf_counter()
        with _threads(self.threads):
            maps = self.pixel_maps(image, alpha)
        mask = instances(
            maps.seg,
            alpha=alpha,
            min_part=self.min_part,
            reach=self.reach,
            edge=self.edge,
            box=maps.box,
            grouping=self.grouping,
        )
        c = int(maps.category.argmax())
        if category is None and CATEGORIES[c] == "other" and maps.category[c] >= 0.5:
            # the training data's "other" furniture has no moving parts (a category the
            # user gives is left alone: their "other" may be a chest with a lid)
            mask = np.where(mask >= 2, 1, mask).astype(mask.dtype)
        elif (
            mask.max() < 2 and self.fallback_movable > 0 and (category or CATEGORIES[c]) != "other"
        ):
            mask = self._fallback_parts(maps, mask)
            if mask.max() >= 2:
                photo = self._photo(maps, mask, t0, category)
                photo.notes.append(
                    "the parser was sure of no moving part; its parts are the likeliest "
                    f"regions (movable share > {self.fallback_movable:g}): check the mask"
                )
                return photo, maps
        return self._photo(maps, mask, t0, category), maps

    def _fallback_parts(self, maps: PixelMaps, mask: np.ndarray) -> np.ndarray:
        """Parts for an object of the seven categories where none was found (a drawer
        front the network is unsure of, on a photo of a desk): within the object's
        silhouette, the pixels whose movable probability is more than ``fallback_movable``
        of their base plus movable probability, grouped as :func:`instances` groups."""
        seg = maps.seg.copy()
        t = self.fallback_movable
        # movable wins the argmax exactly where movable / (base + movable) > t
        seg[2] = seg[2] * (1.0 - t) / t
        return instances(
            seg,
            alpha=mask > 0,
            min_part=self.min_part,
            reach=self.reach,
            edge=self.edge,
            box=maps.box,
            grouping=self.grouping,
        )

    def label(
        self, image: np.ndarray, mask: np.ndarray, category: str | None = None
    ) -> ParsedPhoto:
        """A given part mask (ids 0..K; 1 the base): the category and each region's
        motion (ids >= 2); the mask is returned unchanged. ``category`` as in
        :meth:`parse`."""
        t0 = time.perf_counter()
        mask = np.asarray(mask)
        with _threads(self.threads):
            maps = self.pixel_maps(image, mask > 0)
        return self._photo(maps, mask, t0, category)

    def score_regions(self, image: np.ndarray, regions: list[np.ndarray]) -> RegionScores:
        """How the network sees each candidate region (``RegionScores``)."""
        return self._score_regions(image, regions)[0]

    def _score_regions(
        self, image: np.ndarray, regions: list[np.ndarray]
    ) -> tuple[RegionScores, PixelMaps]:
        parsed, maps = self._parse(image, None)
        probs = maps.seg
        classes = np.zeros((len(regions), 3))
        ids = [p.id for p in parsed.parts]
        overlap = np.zeros((len(regions), len(ids)))
        for r, reg in enumerate(regions):
            reg = np.asarray(reg, bool)
            n = reg.sum()
            if n == 0:
                classes[r] = (1.0, 0.0, 0.0)
                continue
            p = probs[:, reg].mean(1)
            classes[r] = (p[0], p[1], p[2])
            for j, pid in enumerate(ids):
                overlap[r, j] = (parsed.mask[reg] == pid).sum() / n
        return RegionScores(classes, overlap, parsed), maps

    def merge_regions(self, image: np.ndarray, regions: list[np.ndarray]) -> ParsedPhoto:
        """Candidate regions (``(H, W)`` bool each, e.g. SAM2's automatic masks, possibly
        overlapping) -> a ParsedPhoto whose parts are unions of regions: a region that is
        mostly background (network's view) is background, one more part than base joins
        the parse's part it overlaps most (a new part when it overlaps none), the rest is
        base. Larger regions are painted first, so smaller (finer) ones win overlaps;
        pixels no region covers are background."""
        t0 = time.perf_counter()
        scores, maps = self._score_regions(image, regions)
        h, w = scores.parse.mask.shape
        mask = np.zeros((h, w), np.int32)
        order = np.argsort([-np.asarray(r, bool).sum() for r in regions])
        next_new = 1000
        for r in order:
            bg, base, part = scores.classes[r]
            reg = np.asarray(regions[r], bool)
            if bg >= max(base, part):
                label = 0
            elif part > base:
                if scores.overlap.shape[1] and scores.overlap[r].max() > 0.2:
                    label = scores.parse.parts[int(scores.overlap[r].argmax())].id
                else:
                    label, next_new = next_new, next_new + 1
            else:
                label = 1
            mask[reg] = label
        mask = _renumber(mask)
        return self._photo(maps, mask, t0)

    # ------------------------------------------------------------------ helpers

    def _photo(
        self, maps: PixelMaps, mask: np.ndarray, t0: float, category: str | None = None
    ) -> ParsedPhoto:
        parts = []
        prior = self.motion_prior.get(category) if category else None
        for pid in sorted(int(v) for v in np.unique(mask) if v >= 2):
            p = maps.motion[:, mask == pid].mean(1)
            if prior is not None:  # p(m | photo, category) ~ p(m | photo) p(m | category) / p(m)
                p = p * prior
                p = p / max(float(p.sum()), 1e-12)
            k = int(p.argmax())
            parts.append(
                ParsedPart(
                    pid, MOTIONS[k], float(p[k]), dict(zip(MOTIONS, map(float, p), strict=True))
                )
            )
        c = int(maps.category.argmax())
        return ParsedPhoto(
            CATEGORIES[c],
            float(maps.category[c]),
            mask.astype(np.uint8) if mask.dtype != np.uint8 else mask,
            parts,
            time.perf_counter() - t0,
            dict(zip(CATEGORIES, map(float, maps.category), strict=True)),
        )


# --------------------------------------------------------------------------- post-processing


def instances(
    seg: np.ndarray,
    alpha: np.ndarray | None = None,
    min_part: float = 0.004,
    reach: float = 0.04,
    edge: float = 0.5,
    box: np.ndarray | None = None,
    grouping: BoxGrouping | None = None,
) -> np.ndarray:
    """(4, H, W) probabilities (background, base, movable part; a part's edge) -> (H, W)
    uint8 mask: 0 background, 1 base, 2..K parts.

    Parts: with ``box`` (4, H, W) (each pixel's distances to its part's box edges), the
    movable pixels grouped by the box they point to (:func:`box_groups`); without it,
    the 4-connected components of the movable pixels whose edge probability is below
    ``edge``. Parts smaller than ``min_part`` of the object's pixels are dropped; the
    other movable pixels join the nearest part within ``reach`` of the object's size
    (at least 3 px); movable pixels left over form parts of their own when large enough,
    else stay base. ``alpha``: pixels outside are background, inside are object. Ids run
    in reading order of the parts' centres (top to bottom, left to right)."""
    cls = seg[:3].argmax(0)
    if alpha is not None:
        alpha = np.asarray(alpha, bool)
        cls = np.where(alpha, seg[1:3].argmax(0) + 1, 0)
    obj = cls > 0
    n_obj = int(obj.sum())
    out = np.where(obj, 1, 0).astype(np.int32)
    if n_obj == 0:
        return out.astype(np.uint8)
    min_px = max(4, min_part * n_obj)
    movable = cls == 2
    if box is not None:
        parts = box_groups(movable, box, min_px, grouping)
    else:
        parts = _components(movable & (seg[3] < edge), min_px)
    ys, xs = np.nonzero(obj)
    size = max(ys.max() - ys.min(), xs.max() - xs.min()) + 1
    if parts.any():
        dist, (iy, ix) = ndimage.distance_transform_edt(parts == 0, return_indices=True)
        grow = movable & (parts == 0) & (dist <= max(3.0, reach * size))
        parts = np.where(grow, parts[iy, ix], parts)
    rest = _components(movable & (parts == 0), min_px)
    parts = np.where(rest > 0, rest + parts.max(), parts)
    n = int(parts.max())
    if n == 0:
        return out.astype(np.uint8)
    # reading order: by centre row (in bands of 5 % of the object), then column
    idx = np.arange(1, n + 1)
    cy = np.asarray(ndimage.mean(np.indices(parts.shape)[0], parts, idx))
    cx = np.asarray(ndimage.mean(np.indices(parts.shape)[1], parts, idx))
    order = np.lexsort((cx, np.round(cy / (0.05 * size))))
    rank = np.zeros(n + 1, np.int32)
    rank[order + 1] = np.arange(n) + 2
    out = np.where(parts > 0, rank[parts], out)
    return out.astype(np.uint8)


@dataclass(frozen=True)
class BoxGrouping:
    """How :func:`box_groups` makes parts of the movable pixels' part-box votes."""

    iou: float = 0.6  # pixels whose boxes overlap more agree on a part
    merge_iou: float = 0.4  # groups whose boxes overlap more are one part
    min_fill: float = 0.35  # a group must fill this share of its box
    sample: int = 1500  # pixels the mode seeking looks at


def box_groups(
    movable: np.ndarray, box: np.ndarray, min_px: float, grouping: BoxGrouping | None = None
) -> np.ndarray:
    """(H, W) int32 parts 1..n (0 elsewhere) of the ``movable`` pixels grouped by the
    part box each points to (``box`` (4, H, W): distances to its left, top, right and
    bottom edges). Greedy mode seeking on a sample of at most ``sample`` pixels: the
    pixel whose box the most free pixels agree with (IoU above ``iou``) makes a group of
    them, whose box is their median; repeated while a group would hold ``min_px``
    pixels; two groups whose boxes overlap more than ``merge_iou`` are one (adjacent parts'
    boxes hardly overlap; one part's votes may split in bands). Every movable pixel then
    joins, of the group boxes that hold it, the one its own box overlaps most (IoU above
    ``iou`` / 2); a group whose pixels fill less than
    ``min_fill`` of its box (a sliver where the votes of two parts blend) is dropped and
    its pixels go again; a group keeps its largest connected piece and any other piece
    of at least ``min_px`` pixels."""
    g = grouping or BoxGrouping()
    ys, xs = np.nonzero(movable)
    out = np.zeros(movable.shape, np.int32)
    if len(ys) < min_px:
        return out
    d = box[:, ys, xs]  # each pixel's distances to its box's left, top, right, bottom
    boxes = np.stack([xs + 0.5 - d[0], ys + 0.5 - d[1], xs + 0.5 + d[2], ys + 0.5 + d[3]], 1)
    step = max(1, int(np.ceil(len(ys) / g.sample)))
    sub = boxes[::step]
    agree = _box_iou(sub, sub) > g.iou
    free = np.ones(len(sub), bool)
    groups: list[np.ndarray] = []
    while free.any():
        support = (agree & free[None, :]).sum(1) * free
        i = int(support.argmax())
        if support[i] * step < min_px:
            break
        members = free & agree[i]
        groups.append(np.median(sub[members], 0))
        free &= ~members
    if not groups:
        return out
    group_boxes = np.stack(groups)
    while len(group_boxes) > 1:  # one part's votes split in bands: their boxes overlap
        pair = _box_iou(group_boxes, group_boxes) - np.eye(len(group_boxes)) * 2
        a, b = np.unravel_index(int(pair.argmax()), pair.shape)
        if pair[a, b] <= g.merge_iou:
            break
        union = np.concatenate(
            [
                group_boxes[a, :2].clip(None, group_boxes[b, :2]),
                group_boxes[a, 2:].clip(group_boxes[b, 2:]),
            ]
        )
        group_boxes = np.delete(group_boxes, [a, b], 0)
        group_boxes = np.concatenate([group_boxes, union[None]])
    while True:
        best, ok = _assign(boxes, xs, ys, group_boxes, g.iou / 2)
        count = np.bincount(best[ok], minlength=len(group_boxes))
        area = np.prod(group_boxes[:, 2:] - group_boxes[:, :2], 1)
        fill = count / np.maximum(area, 1.0)
        worst = int(fill.argmin())
        if fill[worst] >= g.min_fill or len(group_boxes) == 1:
            break
        group_boxes = np.delete(group_boxes, worst, 0)  # a sliver between two parts
    out[ys[ok], xs[ok]] = best[ok] + 1
    kept = np.zeros_like(out)
    n = 0
    for k in range(1, len(group_boxes) + 1):
        lab, m = ndimage.label(out == k)
        if m == 0:
            continue
        sizes = ndimage.sum_labels(np.ones_like(lab), lab, np.arange(1, m + 1))
        keep = [j + 1 for j in range(m) if sizes[j] >= min_px or j == int(sizes.argmax())]
        piece = np.isin(lab, keep)
        if piece.sum() >= min_px:
            n += 1
            kept[piece] = n
    return kept


def _assign(
    boxes: np.ndarray, xs: np.ndarray, ys: np.ndarray, group_boxes: np.ndarray, least: float
) -> tuple[np.ndarray, np.ndarray]:
    """Each pixel's group: of the group boxes that hold the pixel (with a pixel's slack),
    the one its own box overlaps most; ``ok`` where that overlap is above ``least``."""
    overlap = _box_iou(boxes, group_boxes)  # (N, K)
    inside = (
        (xs[:, None] + 0.5 >= group_boxes[None, :, 0] - 1)
        & (xs[:, None] + 0.5 <= group_boxes[None, :, 2] + 1)
        & (ys[:, None] + 0.5 >= group_boxes[None, :, 1] - 1)
        & (ys[:, None] + 0.5 <= group_boxes[None, :, 3] + 1)
    )
    overlap = np.where(inside, overlap, 0.0)
    best = overlap.argmax(1)
    return best, overlap[np.arange(len(best)), best] > least


def _box_iou(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """(N, 4), (K, 4) boxes (x0, y0, x1, y1) -> (N, K) IoU."""
    w = np.minimum(a[:, None, 2], b[None, :, 2]) - np.maximum(a[:, None, 0], b[None, :, 0])
    h = np.minimum(a[:, None, 3], b[None, :, 3]) - np.maximum(a[:, None, 1], b[None, :, 1])
    inter = np.clip(w, 0, None) * np.clip(h, 0, None)
    area_a = (a[:, 2] - a[:, 0]) * (a[:, 3] - a[:, 1])
    area_b = (b[:, 2] - b[:, 0]) * (b[:, 3] - b[:, 1])
    return inter / np.maximum(area_a[:, None] + area_b[None, :] - inter, 1e-9)


def _motion_prior(counts: dict[str, dict[str, int]]) -> dict[str, np.ndarray]:
    """Per category, p(motion | category) / p(motion) over ``MOTIONS`` from part counts
    (one pseudo-count per motion and category, so no motion is ruled out)."""
    if not counts:
        return {}
    table = {
        c: np.array([per.get(m, 0) for m in MOTIONS], float) + 1.0 for c, per in counts.items()
    }
    marginal = sum(table.values())
    marginal = marginal / marginal.sum()
    return {c: (t / t.sum()) / marginal for c, t in table.items()}


def _components(binary: np.ndarray, min_px: float) -> np.ndarray:
    """(H, W) int32: 4-connected components of ``binary`` with at least ``min_px``
    pixels, numbered 1..n; 0 elsewhere."""
    lab, n = ndimage.label(binary)
    if n == 0:
        return lab.astype(np.int32)
    sizes = ndimage.sum_labels(np.ones_like(lab), lab, np.arange(1, n + 1))
    keep = np.nonzero(sizes >= min_px)[0] + 1
    remap = np.zeros(n + 1, np.int32)
    remap[keep] = np.arange(1, len(keep) + 1)
    return remap[lab]


def _main_object(fg: np.ndarray) -> np.ndarray:
    """The foreground's components that matter: the largest and any other at least a
    fifth of its size (a desk's legs may be apart in a coarse map)."""
    lab, n = ndimage.label(fg)
    if n <= 1:
        return fg
    sizes = ndimage.sum_labels(np.ones_like(lab), lab, np.arange(1, n + 1))
    keep = np.nonzero(sizes >= 0.2 * sizes.max())[0] + 1
    return np.isin(lab, keep)


def _renumber(mask: np.ndarray) -> np.ndarray:
    """Ids >= 2 made consecutive (2, 3, ...) in order of first appearance by value."""
    out = np.where(mask == 1, 1, 0).astype(np.int32)
    for k, v in enumerate(sorted(int(v) for v in np.unique(mask) if v >= 2)):
        out[mask == v] = k + 2
    return out


def _rgb(image: np.ndarray) -> np.ndarray:
    image = np.asarray(image)
    if image.ndim == 2:
        image = np.repeat(image[..., None], 3, -1)
    if image.shape[-1] == 4:
        image = image[..., :3]
    if image.dtype != np.uint8:
        image = np.clip(image * (255.0 if image.max() <= 1.0 else 1.0), 0, 255).astype(np.uint8)
    return np.ascontiguousarray(image)


class _threads:
    """Temporarily set torch's intra-op threads (None: leave as is)."""

    def __init__(self, n: int | None) -> None:
        self.n, self.old = n, None

    def __enter__(self) -> None:
        if self.n:
            self.old = torch.get_num_threads()
            torch.set_num_threads(self.n)

    def __exit__(self, *exc: object) -> None:
        if self.old:
            torch.set_num_threads(self.old)

"""The parser's training data: a torch Dataset over the parser-data format, augmented.

Format (written by the data engine; ``docs/parser.md``)::

    DATA/manifest.json   {"schema": "pact.parser_data", "version": 1, "image_size": 256,
                          "categories": [...8], "motions": [...6],
                          "items": [{"id", "object", "category", "style", "split"}], ...}
    DATA/images/<id>.png, <id>.mask.png (0 bg, 1 base, 2..K movable parts),
    DATA/images/<id>.json  {"category": ..., "parts": {"2": {"motion": "door_left"}, ...}}

``ParserDataset[(index, seed)]`` returns one training sample (the key's seed draws every
augmentation, so a resumed run sees exactly what an uninterrupted one would):

    image     (3, S, S) float32 in [0, 1]
    seg       (S/2, S/2) int64: 0 background, 1 base, 2 movable part
    boundary  (S/2, S/2) float32: 1 on both sides of where a part meets another or the base
    motion    (S/2, S/2) int64: index into MOTIONS on movable pixels, -1 elsewhere
    category  () int64: index into CATEGORIES

Augmentation (what differs between a render and a photo): a random crop round the
object (it fills 35-100 % of the frame, off centre, slightly stretched and turned, the
out-of-image area a flat colour as a letterbox would be), a horizontal flip that swaps
``door_left`` and ``door_right``, colour (brightness, contrast, gamma, saturation, hue,
white balance, sometimes the object re-tinted or the photo grey), blur, sensor noise,
a lower resolution and JPEG artefacts. ``targets`` turns a part mask into the seg, boundary
and motion maps (also used by the tests and the benchmark).
"""

from __future__ import annotations

import json
import logging
from collections.abc import Iterator, Sequence
from dataclasses import dataclass
from pathlib import Path

import cv2
import numpy as np
import torch
from PIL import Image
from torch.utils.data import Dataset

from generator.motions import MOTIONS
from generator.parser.model import CATEGORIES

log = logging.getLogger(__name__)

SCHEMA = "pact.parser_data"
#: Motion index after a horizontal flip (left and right doors swap; the rest stay).
FLIP_MOTION = np.array(
    [
        MOTIONS.index({"door_left": "door_right", "door_right": "door_left"}.get(m, m))
        for m in MOTIONS
    ]
)


class ParserDataError(ValueError):
    """A folder that is not parser data, or an item that cannot be read."""


def read_manifest(root: str | Path) -> dict:
    path = Path(root) / "manifest.json"
    if not path.is_file():
        raise ParserDataError(f"{path}: not found (parser data holds manifest.json and images/)")
    d = json.loads(path.read_text())
    if d.get("schema") != SCHEMA:
        raise ParserDataError(f"{path}: schema {d.get('schema')!r}, expected {SCHEMA!r}")
    return d


def load_item(root: str | Path, item_id: str) -> tuple[np.ndarray, np.ndarray, dict]:
    """(H, W, 3) uint8 RGB, (H, W) uint8 mask, hints dict of one item."""
    base = Path(root) / "images" / item_id
    image = np.asarray(Image.open(f"{base}.png").convert("RGB"))
    mask = np.asarray(Image.open(f"{base}.mask.png"))
    if mask.ndim == 3:
        mask = mask[..., 0]
    hints = json.loads(Path(f"{base}.json").read_text())
    return image, mask, hints


MOTION_PRIOR_NAME = "motion_prior.json"


def motion_counts(root: str | Path) -> dict[str, dict[str, int]]:
    """Per category, how many visible movable parts of the ``train`` items have each
    motion: what the data says a category's parts do (a fridge's doors are side-hinged,
    a dishwasher's bottom-hinged). The parser weighs a part's motion by it when the
    category is known (``PhotoParser.label``'s ``category``)."""
    manifest = read_manifest(root)
    counts: dict[str, dict[str, int]] = {}
    for item in manifest["items"]:
        if item.get("split") != "train":
            continue
        hints = json.loads((Path(root) / "images" / f"{item['id']}.json").read_text())
        per = counts.setdefault(item["category"], {})
        for part in hints.get("parts", {}).values():
            per[part["motion"]] = per.get(part["motion"], 0) + 1
    return counts


def write_motion_prior(root: str | Path, weights: str | Path) -> Path:
    """``weights``/motion_prior.json: :func:`motion_counts` of the data at ``root``."""
    path = Path(weights) / MOTION_PRIOR_NAME
    data = {"data": str(root), "counts": motion_counts(root)}
    path.write_text(json.dumps(data, indent=1, sort_keys=True))
    return path


def motion_lut(hints: dict, flip: bool = False) -> np.ndarray:
    """(256,) int64: mask id -> motion index (-1 for background, base and unknown ids)."""
    lut = np.full(256, -1, np.int64)
    for k, v in (hints.get("parts") or {}).items():
        m = v.get("motion") if isinstance(v, dict) else v
        if m in MOTIONS:
            idx = MOTIONS.index(m)
            lut[int(k)] = FLIP_MOTION[idx] if flip else idx
    return lut


def targets(
    mask: np.ndarray, lut: np.ndarray, out_size: int
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Part mask (S, S) ids -> at the output resolution (out, out): seg int64
    (SEG_CLASSES: 0 background, 1 base, 2 movable part), boundary float32 (1 where a
    3 x 3 neighbourhood inside the object holds two ids, one of them a movable part:
    both sides of where a part meets another part or the base) and motion int64
    (MOTIONS index on movable pixels, -1 elsewhere)."""
    m = cv2.resize(mask, (out_size, out_size), interpolation=cv2.INTER_NEAREST)
    kernel = np.ones((3, 3), np.uint8)
    edge = cv2.dilate(m, kernel) != cv2.erode(m, kernel)
    inside = cv2.erode((m > 0).astype(np.uint8), kernel) > 0
    near_part = cv2.dilate((m >= 2).astype(np.uint8), kernel) > 0
    boundary = (edge & inside & near_part).astype(np.float32)
    seg = np.minimum(m, 2).astype(np.int64)
    motion = np.where(m >= 2, lut[m], -1)
    return seg, boundary, motion


def box_targets(mask: np.ndarray, out_size: int) -> np.ndarray:
    """Part mask (S, S) ids -> (4, out, out) float32: on a movable part's pixel the
    distances from the pixel's centre to its part's box (left, top, right, bottom edges;
    the box of the part's pixels at the output resolution), as fractions of ``out``;
    0 elsewhere."""
    m = cv2.resize(mask, (out_size, out_size), interpolation=cv2.INTER_NEAREST)
    out = np.zeros((4, out_size, out_size), np.float32)
    ys, xs = np.indices(m.shape, dtype=np.float32)
    ys, xs = ys + 0.5, xs + 0.5
    for v in np.unique(m):
        if v < 2:
            continue
        on = m == v
        py, px = np.nonzero(on)
        x0, x1, y0, y1 = px.min(), px.max() + 1, py.min(), py.max() + 1
        out[0][on] = xs[on] - x0
        out[1][on] = ys[on] - y0
        out[2][on] = x1 - xs[on]
        out[3][on] = y1 - ys[on]
    return out / out_size


@dataclass(frozen=True)
class AugmentConfig:
    fill: tuple[float, float] = (0.35, 1.0)  # the object's longer side over the crop side
    stretch: float = 0.12  # log aspect jitter
    rotate: float = 6.0  # degrees
    flip: float = 0.5
    color: float = 0.9
    retint: float = 0.2  # the object's pixels get a random tint
    gray: float = 0.05
    blur: float = 0.3
    noise: float = 0.4
    lowres: float = 0.2
    jpeg: float = 0.4


def _crop_matrix(
    mask: np.ndarray, size: int, rng: np.random.Generator, cfg: AugmentConfig
) -> tuple[np.ndarray, bool]:
    """2 x 3 affine (image -> crop) framing the object; and whether to flip."""
    ys, xs = np.nonzero(mask)
    H, W = mask.shape
    if len(ys) == 0:
        y0, y1, x0, x1 = 0, H, 0, W
    else:
        y0, y1, x0, x1 = ys.min(), ys.max() + 1, xs.min(), xs.max() + 1
    cy, cx = (y0 + y1) / 2, (x0 + x1) / 2
    extent = max(y1 - y0, x1 - x0, 8)
    fill = rng.uniform(*cfg.fill)
    side = min(extent / fill, max(extent, 1.2 * max(H, W)))  # crop side in image pixels
    slack = max(0.0, (side - extent) / 2)
    cx += rng.uniform(-slack, slack) * 0.8
    cy += rng.uniform(-slack, slack) * 0.8
    s = size / side
    st = np.exp(rng.uniform(-cfg.stretch, cfg.stretch))
    sx, sy = s * st, s / st
    a = np.deg2rad(rng.uniform(-cfg.rotate, cfg.rotate))
    c, si = np.cos(a), np.sin(a)
    flip = rng.random() < cfg.flip
    fx = -1.0 if flip else 1.0
    R = np.array([[fx * sx * c, -fx * sx * si], [sy * si, sy * c]])
    t = np.array([size / 2, size / 2]) - R @ np.array([cx, cy])
    return np.concatenate([R, t[:, None]], 1), flip


def _color(
    img: np.ndarray, mask: np.ndarray, rng: np.random.Generator, cfg: AugmentConfig
) -> np.ndarray:
    """img (S, S, 3) float32 in [0, 1] -> photometrically changed copy."""
    if rng.random() < cfg.retint:
        fg = mask > 0
        luma = img @ np.array([0.299, 0.587, 0.114], np.float32)
        tint = rng.uniform(0.2, 1.0, 3).astype(np.float32)
        w = rng.uniform(0.4, 1.0)
        img = img.copy()
        img[fg] = img[fg] * (1 - w) + np.clip(1.6 * luma[fg, None] * tint, 0, 1) * w
    if rng.random() < cfg.color:
        hsv = cv2.cvtColor(img, cv2.COLOR_RGB2HSV)  # H in degrees
        hsv[..., 0] = (hsv[..., 0] + rng.uniform(-18, 18)) % 360
        hsv[..., 1] = np.clip(hsv[..., 1] * rng.uniform(0.5, 1.4), 0, 1)
        img = cv2.cvtColor(hsv, cv2.COLOR_HSV2RGB)
        img = img * rng.uniform(0.85, 1.15, 3).astype(np.float32)  # white balance
        mean = img.mean()
        img = (img - mean) * rng.uniform(0.65, 1.35) + mean
        img = img * rng.uniform(0.65, 1.35)
        img = np.clip(img, 0, 1) ** rng.uniform(0.7, 1.4)
    if rng.random() < cfg.gray:
        img = np.repeat(img @ np.array([[0.299], [0.587], [0.114]], np.float32), 3, -1)
    return np.clip(img, 0, 1).astype(np.float32)


def _degrade(img: np.ndarray, rng: np.random.Generator, cfg: AugmentConfig) -> np.ndarray:
    S = img.shape[0]
    if rng.random() < cfg.lowres:
        k = rng.uniform(0.4, 0.8)
        small = cv2.resize(img, (max(8, int(S * k)),) * 2, interpolation=cv2.INTER_AREA)
        img = cv2.resize(small, (S, S), interpolation=cv2.INTER_LINEAR)
    if rng.random() < cfg.blur:
        img = cv2.GaussianBlur(img, (0, 0), rng.uniform(0.3, 1.3))
    if rng.random() < cfg.noise:
        sigma = rng.uniform(0.005, 0.035)
        img = img + rng.normal(0, sigma, img.shape).astype(np.float32) * np.sqrt(img + 0.05)
    img = np.clip(img, 0, 1)
    if rng.random() < cfg.jpeg:
        u8 = (img * 255 + 0.5).astype(np.uint8)
        ok, buf = cv2.imencode(
            ".jpg", u8[..., ::-1], [cv2.IMWRITE_JPEG_QUALITY, int(rng.integers(30, 92))]
        )
        if ok:
            img = cv2.imdecode(buf, cv2.IMREAD_COLOR)[..., ::-1].astype(np.float32) / 255
    return img


def augment(
    image: np.ndarray, mask: np.ndarray, size: int, rng: np.random.Generator, cfg: AugmentConfig
) -> tuple[np.ndarray, np.ndarray, bool]:
    """(H, W, 3) uint8, (H, W) ids -> (size, size, 3) float32, (size, size) uint8, flipped."""
    M, flip = _crop_matrix(mask, size, rng, cfg)
    pad = tuple(float(v) for v in rng.choice([0.0, 0.5, 1.0, rng.random()], 1).repeat(3) * 255)
    img = cv2.warpAffine(
        image,
        M,
        (size, size),
        flags=cv2.INTER_LINEAR,
        borderMode=cv2.BORDER_CONSTANT,
        borderValue=pad,
    )
    m = cv2.warpAffine(
        mask,
        M,
        (size, size),
        flags=cv2.INTER_NEAREST,
        borderMode=cv2.BORDER_CONSTANT,
        borderValue=0,
    )
    img = img.astype(np.float32) / 255
    img = _color(img, m, rng, cfg)
    img = _degrade(img, rng, cfg)
    return img, m, flip


def letterbox_matrix(h: int, w: int, size: int) -> np.ndarray:
    """2 x 3 affine: an (h, w) photo scaled to fit a size x size square, centred."""
    s = size / max(h, w)
    return np.array([[s, 0, (size - s * w) / 2], [0, s, (size - s * h) / 2]])


def split_items(root: str | Path, split: str = "train") -> list[dict]:
    """The items of one split of a parser-data folder whose files are on disk."""
    root = Path(root)
    return [
        it
        for it in read_manifest(root)["items"]
        if it.get("split", "train") == split
        and (root / "images" / f"{it['id']}.mask.png").is_file()
    ]


def mixed_items(
    root: str | Path,
    extra: str | Path | Sequence[str | Path],
    repeat: int,
    split: str = "train",
) -> list[dict]:
    """The items of ``root`` and, ``repeat`` times over, those of one or more other
    folders (each item carrying its ``root``): a small set of other photos (renders of
    real objects) weighed into the training of a large one, or more procedural folders
    of other seeds (``repeat`` 1)."""
    own = split_items(root, split)
    folders = [extra] if isinstance(extra, (str, Path)) else list(extra)
    other = [dict(it, root=str(f)) for f in folders for it in split_items(f, split)]
    return own + other * repeat


class ParserDataset(Dataset):
    """Items of one split of a parser-data folder (or the given items, each read from
    its ``root`` if it names one); keys are (index, seed) pairs."""

    def __init__(
        self,
        root: str | Path,
        split: str = "train",
        size: int = 192,
        augment: bool = True,
        cfg: AugmentConfig | None = None,
        items: Sequence[dict] | None = None,
    ) -> None:
        self.root = Path(root)
        self.size = size
        self.augment = augment
        self.cfg = cfg or AugmentConfig()
        self.items = list(split_items(self.root, split) if items is None else items)

    def __len__(self) -> int:
        return len(self.items)

    def __getitem__(self, key: tuple[int, int] | int) -> dict[str, torch.Tensor]:
        index, seed = key if isinstance(key, tuple) else (key, 0)
        item = self.items[index]
        image, mask, hints = load_item(item.get("root", self.root), item["id"])
        rng = np.random.default_rng([seed, index])
        if self.augment:
            img, m, flip = augment(image, mask, self.size, rng, self.cfg)
        else:
            M = letterbox_matrix(*mask.shape, self.size)
            img = (
                cv2.warpAffine(
                    image, M, (self.size,) * 2, flags=cv2.INTER_AREA, borderValue=(255, 255, 255)
                ).astype(np.float32)
                / 255
            )
            m = cv2.warpAffine(mask, M, (self.size,) * 2, flags=cv2.INTER_NEAREST, borderValue=0)
            flip = False
        seg, boundary, motion = targets(m, motion_lut(hints, flip), self.size // 2)
        cat = hints.get("category", item.get("category", "other"))
        return {
            "box": torch.from_numpy(box_targets(m, self.size // 2)),
            "image": torch.from_numpy(np.ascontiguousarray(img.transpose(2, 0, 1))),
            "seg": torch.from_numpy(seg),
            "boundary": torch.from_numpy(boundary),
            "motion": torch.from_numpy(motion),
            "category": torch.tensor(
                CATEGORIES.index(cat) if cat in CATEGORIES else CATEGORIES.index("other")
            ),
        }


class StepBatches:
    """Batch sampler: batch ``step`` is ``batch`` (index, seed) keys drawn from (seed, step),
    for steps ``start`` .. ``stop - 1``: a resumed run draws the same batches."""

    def __init__(self, n: int, batch: int, seed: int, start: int, stop: int) -> None:
        self.n, self.batch, self.seed, self.start, self.stop = n, batch, seed, start, stop

    def __len__(self) -> int:
        return max(0, self.stop - self.start)

    def __iter__(self) -> Iterator[list[tuple[int, int]]]:
        for step in range(self.start, self.stop):
            rng = np.random.default_rng([self.seed, step])
            idx = rng.integers(0, self.n, self.batch)
            yield [(int(i), int(self.seed * 1_000_003 + step)) for i in idx]

"""SAM2's automatic masks as candidate regions for the photo parser (the paper's mask path).

    seg = Sam2Segmenter.from_checkpoint("sam2.1_hiera_tiny.pt")   # config from the name
    regions = seg.regions(image)          # (H, W, 3) uint8 -> [(H, W) bool], largest first
    parsed = seg.segment(image, parser)   # = parser.merge_regions(image, seg.regions(image))

PAct gets its part masks by running SAM2's automatic mask generator on the photo and
letting a vision-language model merge the fragments into parts and label each one moving
or fixed (pact-paper.tex, appendix "VLM-Guided Part Analysis"). Here the photo parser
(``PhotoParser.merge_regions``) takes the VLM's place; this module is the SAM2 half.

SAM2 is optional (``pip install sam2==1.1.0``, or the ``sam2`` extra of this project)
and is imported only when a segmenter is made. Its checkpoints are Meta's SAM2 release
files (``sam2.1_hiera_tiny.pt`` ...), which the user downloads; nothing here downloads
anything. Runs on CPU: SAM2's one CUDA-only step (its compiled connected-components
kernel, used to remove specks and fill holes when ``min_mask_region_area`` > 0) is left
off and specks are removed here with scipy instead. See docs/segmenters.md.
"""

from __future__ import annotations

import logging
import time
from dataclasses import dataclass
from pathlib import Path
from typing import TYPE_CHECKING, Any, Protocol

import numpy as np
from PIL import Image
from scipy import ndimage

if TYPE_CHECKING:
    from generator.parser.inference import ParsedPhoto

log = logging.getLogger(__name__)

INSTALL_HINT = (
    "SAM2 is an optional dependency of pact-sim: install it with `pip install sam2==1.1.0` "
    "(or `pip install 'pact-sim[sam2]'`), or give the photo a part mask instead"
)

#: Config name -> the config file inside the sam2 package. The SAM 2.1 names go with the
#: sam2.1_hiera_*.pt checkpoints, the SAM 2 names with the older sam2_hiera_*.pt ones.
CONFIGS: dict[str, str] = {
    f"{family}_hiera_{size}": f"configs/{family}/{family}_hiera_{size}.yaml"
    for family in ("sam2.1", "sam2")
    for size in ("t", "s", "b+", "l")
}
DEFAULT_CONFIG = "sam2.1_hiera_t"

#: The file names of Meta's released checkpoints -> the config each goes with.
OFFICIAL_CHECKPOINTS: dict[str, str] = {
    f"{family}_hiera_{name}.pt": f"{family}_hiera_{size}"
    for family in ("sam2.1", "sam2")
    for name, size in (("tiny", "t"), ("small", "s"), ("base_plus", "b+"), ("large", "l"))
}


class Sam2SegmenterError(Exception):
    """SAM2 cannot be used: not installed, or a checkpoint that does not fit."""


class Sam2NotInstalledError(Sam2SegmenterError, ImportError):
    """The optional ``sam2`` package (or one of its own dependencies) is missing."""


class Sam2CheckpointError(Sam2SegmenterError, ValueError):
    """A checkpoint file that is missing, unreadable, or made for another config."""


class RegionMerger(Protocol):
    """What ``Sam2Segmenter.segment`` needs of a parser (``PhotoParser`` has it)."""

    def merge_regions(self, image: np.ndarray, regions: list[np.ndarray]) -> ParsedPhoto: ...


@dataclass
class Sam2Settings:
    """How SAM2's automatic mask generator samples and filters masks, and what is dropped
    afterwards. Defaults suit photos of furniture fronts: large flat doors and drawer
    fronts with small handles, where a missed handle or a door split in two costs more than
    an extra fragment (the parser merges fragments; it cannot find what is missing)."""

    # A points_per_side x points_per_side grid of single-point prompts over the photo.
    # 16: a point every 1/16 of the photo, about 12 a side on an object that fills three
    # quarters of it, two or more on each front of a four-drawer chest. The decoder runs
    # once per prompt and dominates the cost on CPU, which grows with the square: SAM2's
    # default 32 (which also catches most handles) costs about four times as much
    # (docs/segmenters.md, "Cost"); use it on a GPU.
    points_per_side: int = 16
    # Prompts run through the mask decoder at once (memory vs. speed only).
    points_per_batch: int = 64
    # Keep a mask whose predicted IoU (the model's own quality estimate) exceeds this.
    # SAM2's default is 0.8; 0.7 keeps the less certain panels of plain, evenly lit fronts.
    pred_iou_thresh: float = 0.7
    # Keep a mask whose stability score (IoU of the mask thresholded at +-offset) is at
    # least this. SAM2's default 0.95 drops doors whose seam to the next door is faint.
    stability_score_thresh: float = 0.9
    stability_score_offset: float = 1.0
    # Box non-maximum suppression between masks of one photo (SAM2's default).
    box_nms_thresh: float = 0.7
    # Extra passes on zoomed crops (each layer i adds 4**i encoder runs): off on CPU.
    crop_n_layers: int = 0
    # A second decoder pass refining each mask with its own prediction: off (twice the
    # decoder's cost for sharper edges the parser does not need).
    use_m2m: bool = False
    # Dropped afterwards (here, with scipy): specks and masks smaller than
    # max(min_region_pixels, min_region_fraction of the photo) ...
    min_region_fraction: float = 0.0005
    min_region_pixels: int = 16
    # ... and a mask whose IoU with a better-scored kept mask is at least this.
    duplicate_iou: float = 0.9
    # A photo whose long side is above this is shrunk to it for SAM2 and the masks are
    # scaled back (nearest). SAM2 reads the photo at 1024 px and predicts 256 x 256 mask
    # logits, so more pixels add no detail, only work: it upsamples every candidate mask
    # (points_per_batch x 3 at once) to the size it is given before filtering.
    max_side: int = 1024

    def generator_kwargs(self) -> dict[str, Any]:
        """The keyword arguments of ``SAM2AutomaticMaskGenerator`` these settings set."""
        return {
            "points_per_side": self.points_per_side,
            "points_per_batch": self.points_per_batch,
            "pred_iou_thresh": self.pred_iou_thresh,
            "stability_score_thresh": self.stability_score_thresh,
            "stability_score_offset": self.stability_score_offset,
            "box_nms_thresh": self.box_nms_thresh,
            "crop_n_layers": self.crop_n_layers,
            "use_m2m": self.use_m2m,
            "min_mask_region_area": 0,  # > 0 runs SAM2's CUDA-only connected components
            "output_mode": "binary_mask",
            "multimask_output": True,
        }


def import_sam2() -> Any:
    """The ``sam2`` package, or Sam2NotInstalledError saying how to install it."""
    try:
        import sam2  # noqa: F401  (sets up SAM2's config search path)
        import sam2.automatic_mask_generator
        import sam2.build_sam
    except ImportError as e:
        raise Sam2NotInstalledError(f"cannot import SAM2 ({e}). {INSTALL_HINT}") from e
    return sam2


def config_file(config: str) -> str:
    """A config name (``sam2.1_hiera_t``) -> its file inside the sam2 package."""
    if config in CONFIGS:
        return CONFIGS[config]
    if config in CONFIGS.values():
        return config
    known = ", ".join(CONFIGS)
    raise Sam2SegmenterError(f"unknown SAM2 config {config!r}; the package's configs: {known}")


def config_for_checkpoint(path: str | Path) -> str | None:
    """The config an official checkpoint file name goes with, None for other names."""
    return OFFICIAL_CHECKPOINTS.get(Path(path).name)


def clean_regions(
    masks: list[np.ndarray],
    scores: list[float] | np.ndarray,
    *,
    min_area: int,
    duplicate_iou: float,
) -> list[np.ndarray]:
    """Candidate masks (H, W) bool with a quality score each -> the masks to keep,
    largest area first.

    Connected pieces smaller than ``min_area`` pixels are removed from each mask, then
    masks smaller than ``min_area`` are dropped. In order of score (best first), a mask
    whose IoU with an already kept one is at least ``duplicate_iou`` is dropped.
    """
    if len(masks) != len(scores):
        raise ValueError(f"{len(masks)} masks but {len(scores)} scores")
    cleaned: list[tuple[np.ndarray, float, int, tuple[slice, slice]]] = []
    for mask, score in zip(masks, scores, strict=True):
        mask = _without_specks(np.asarray(mask, bool), min_area)
        area = int(mask.sum())
        if area < max(min_area, 1):
            continue
        cleaned.append((mask, float(score), area, _bbox(mask)))
    kept: list[tuple[np.ndarray, float, int, tuple[slice, slice]]] = []
    for item in sorted(cleaned, key=lambda t: -t[1]):
        if not any(_iou_at_least(item, other, duplicate_iou) for other in kept):
            kept.append(item)
    kept.sort(key=lambda t: (-t[2], -t[1]))
    return [np.ascontiguousarray(m) for m, _, _, _ in kept]


class Sam2Segmenter:
    """SAM2's automatic mask generator around one SAM2 model (eval mode).

    ``model`` is a ``sam2.modeling.sam2_base.SAM2Base``; ``from_checkpoint`` builds one from
    a config and a checkpoint file.
    """

    def __init__(self, model: Any, settings: Sam2Settings | None = None) -> None:
        sam2 = import_sam2()
        self.model = model.eval()
        self.settings = settings or Sam2Settings()
        self.config: str | None = None  # set by from_checkpoint
        self.checkpoint: Path | None = None
        self.generator = sam2.automatic_mask_generator.SAM2AutomaticMaskGenerator(
            self.model, **self.settings.generator_kwargs()
        )
        # SAM2ImagePredictor assumes the 1024 px input of the released configs; a model
        # built at another image_size has its backbone features at these sizes instead.
        s = int(self.model.image_size)
        self.generator.predictor._bb_feat_sizes = [
            (s // 4, s // 4),
            (s // 8, s // 8),
            (s // 16, s // 16),
        ]

    @classmethod
    def from_checkpoint(
        cls,
        path: str | Path,
        config: str | None = None,
        device: str = "cpu",
        *,
        settings: Sam2Settings | None = None,
        image_size: int | None = None,
    ) -> Sam2Segmenter:
        """Build SAM2 from one of the package's configs and load a checkpoint.

        ``config``: a name of ``CONFIGS`` (``sam2.1_hiera_t``, ``sam2.1_hiera_s``,
        ``sam2.1_hiera_b+``, ``sam2.1_hiera_l``, and the ``sam2_hiera_*`` ones); None takes
        the config an official file name goes with (``sam2.1_hiera_large.pt`` ->
        ``sam2.1_hiera_l``), else ``sam2.1_hiera_t``. ``path``: a checkpoint as Meta
        releases them (``{"model": state_dict}``) or a bare state dict. ``device``:
        ``"cpu"`` (works everywhere) or ``"cuda"``. ``image_size``: the model's input
        side in pixels, a multiple of 32; None keeps the config's 1024, the size the
        released weights were trained at (smaller is faster and worse; tests use it).

        Raises Sam2NotInstalledError without the sam2 package, Sam2CheckpointError for a
        checkpoint that is missing, unreadable or made for another config.
        """
        sam2 = import_sam2()
        import torch

        path = Path(path)
        config = config or config_for_checkpoint(path) or DEFAULT_CONFIG
        cfg_file = config_file(config)
        if image_size is not None and (image_size < 64 or image_size % 32):
            raise Sam2SegmenterError(
                f"image_size must be a multiple of 32, >= 64; got {image_size}"
            )
        if str(device).startswith("cuda") and not torch.cuda.is_available():
            raise Sam2SegmenterError(f"device {device!r}: CUDA is not available here; use 'cpu'")
        state = _read_state_dict(path)
        t0 = time.perf_counter()
        overrides = [] if image_size is None else [f"++model.image_size={int(image_size)}"]
        model = sam2.build_sam.build_sam2(
            cfg_file, ckpt_path=None, device="cpu", hydra_overrides_extra=overrides
        )
        _check_fits(model, state, path, config)
        model.load_state_dict(state, strict=True)
        model = model.to(device)
        log.info("SAM2 %s from %s on %s in %.1f s", config, path, device, time.perf_counter() - t0)
        segmenter = cls(model, settings)
        segmenter.config, segmenter.checkpoint = config, path
        return segmenter

    def regions(self, image: np.ndarray) -> list[np.ndarray]:
        """The photo's candidate regions: (H, W) bool masks, none empty, largest first,
        specks, tiny masks and near-duplicates dropped (``Sam2Settings``)."""
        image = np.asarray(image)
        if image.ndim != 3 or image.shape[2] != 3 or image.dtype != np.uint8:
            raise ValueError(f"image must be (H, W, 3) uint8, got {image.shape} {image.dtype}")
        t0 = time.perf_counter()
        s = self.settings
        h, w = image.shape[:2]
        work = _shrunk(image, s.max_side)
        records = self.generator.generate(work)
        wh, ww = work.shape[:2]
        min_area = max(s.min_region_pixels, int(np.ceil(s.min_region_fraction * wh * ww)))
        masks = [np.asarray(r["segmentation"], bool) for r in records]
        scores = [float(r["predicted_iou"]) * float(r["stability_score"]) for r in records]
        regions = clean_regions(masks, scores, min_area=min_area, duplicate_iou=s.duplicate_iou)
        if (wh, ww) != (h, w):
            regions = [_resized_mask(m, h, w) for m in regions]
            regions.sort(key=lambda m: -int(m.sum()))  # stable: ties keep their order
        log.info(
            "SAM2: %d masks -> %d regions in %.1f s",
            len(records),
            len(regions),
            time.perf_counter() - t0,
        )
        return regions

    def segment(self, image: np.ndarray, parser: RegionMerger) -> ParsedPhoto:
        """The photo's part mask and labels: SAM2's regions merged by the parser."""
        return parser.merge_regions(image, self.regions(image))


# --------------------------------------------------------------------------- helpers


def _read_state_dict(path: Path) -> dict:
    import torch

    if not path.exists():
        raise Sam2CheckpointError(
            f"SAM2 checkpoint {path} does not exist: download one of Meta's SAM2 checkpoints "
            f"({', '.join(list(OFFICIAL_CHECKPOINTS)[:4])}) and pass its path "
            "(docs/segmenters.md)"
        )
    if not path.is_file():
        raise Sam2CheckpointError(f"SAM2 checkpoint {path} is not a file")
    try:
        ckpt = torch.load(path, map_location="cpu", weights_only=True)
    except Exception as e:  # unpickling, zip and permission errors alike
        reason = str(e).strip().splitlines()[0] if str(e).strip() else type(e).__name__
        raise Sam2CheckpointError(
            f"SAM2 checkpoint {path} cannot be read as a PyTorch checkpoint: {reason}"
        ) from e
    state = ckpt.get("model", ckpt) if isinstance(ckpt, dict) else None
    if (
        not isinstance(state, dict)
        or not state
        or not all(isinstance(v, torch.Tensor) for v in state.values())
    ):
        raise Sam2CheckpointError(
            f"SAM2 checkpoint {path} holds no model weights (expected {{'model': state_dict}} "
            "as in Meta's release, or a state dict)"
        )
    return state


def _check_fits(model: Any, state: dict, path: Path, config: str) -> None:
    """Sam2CheckpointError unless ``state`` has exactly the model's weights and shapes."""
    own = model.state_dict()
    missing = [k for k in own if k not in state]
    unexpected = [k for k in state if k not in own]
    reshaped = [
        f"{k} {tuple(state[k].shape)} vs {tuple(v.shape)}"
        for k, v in own.items()
        if k in state and tuple(state[k].shape) != tuple(v.shape)
    ]
    if not (missing or unexpected or reshaped):
        return
    problems = []
    for what, items in (
        ("missing", missing),
        ("unexpected", unexpected),
        ("of another shape", reshaped),
    ):
        if items:
            problems.append(f"{len(items)} weights {what} (e.g. {', '.join(items[:2])})")
    named = config_for_checkpoint(path)
    if named and named != config:
        hint = f"its file name says it goes with config {named!r}"
    else:
        hint = "docs/segmenters.md lists the official checkpoints and their configs"
    raise Sam2CheckpointError(
        f"SAM2 checkpoint {path} does not match config {config!r}: {'; '.join(problems)}; {hint}"
    )


def _shrunk(image: np.ndarray, max_side: int) -> np.ndarray:
    """``image`` with its long side at most ``max_side`` (area-averaged), writeable and
    contiguous (torchvision warns on read-only arrays such as PIL's)."""
    h, w = image.shape[:2]
    if max(h, w) <= max_side:
        ok = image.flags.c_contiguous and image.flags.writeable
        return image if ok else image.copy()
    scale = max_side / max(h, w)
    size = (max(1, round(w * scale)), max(1, round(h * scale)))
    return np.array(Image.fromarray(image).resize(size, Image.Resampling.BOX))


def _resized_mask(mask: np.ndarray, h: int, w: int) -> np.ndarray:
    """(h', w') bool -> (h, w) bool, nearest pixel."""
    rows = np.minimum((np.arange(h) + 0.5) * mask.shape[0] / h, mask.shape[0] - 1).astype(int)
    cols = np.minimum((np.arange(w) + 0.5) * mask.shape[1] / w, mask.shape[1] - 1).astype(int)
    return np.ascontiguousarray(mask[rows[:, None], cols[None, :]])


def _without_specks(mask: np.ndarray, min_area: int) -> np.ndarray:
    """``mask`` without its connected pieces (8-connected) smaller than ``min_area``."""
    if min_area <= 1 or not mask.any():
        return mask
    box = _bbox(mask)
    crop = mask[box]
    labels, n = ndimage.label(crop, structure=np.ones((3, 3), bool))
    if n <= 1:
        return mask if crop.sum() >= min_area else np.zeros_like(mask)
    sizes = np.bincount(labels.ravel())
    keep = sizes >= min_area
    keep[0] = False
    out = np.zeros_like(mask)
    out[box] = keep[labels]
    return out


def _bbox(mask: np.ndarray) -> tuple[slice, slice]:
    rows = np.flatnonzero(mask.any(1))
    cols = np.flatnonzero(mask.any(0))
    if not len(rows):
        return slice(0, 0), slice(0, 0)
    return slice(rows[0], rows[-1] + 1), slice(cols[0], cols[-1] + 1)


def _iou_at_least(a: tuple, b: tuple, threshold: float) -> bool:
    (ma, _, area_a, box_a), (mb, _, area_b, box_b) = a, b
    if min(area_a, area_b) < threshold * max(area_a, area_b):
        return False  # IoU <= smaller / larger area
    r0, r1 = min(box_a[0].start, box_b[0].start), max(box_a[0].stop, box_b[0].stop)
    c0, c1 = min(box_a[1].start, box_b[1].start), max(box_a[1].stop, box_b[1].stop)
    inter = int(np.logical_and(ma[r0:r1, c0:c1], mb[r0:r1, c0:c1]).sum())
    return inter >= threshold * (area_a + area_b - inter)

"""The photo of an input item: decoding, checks and its silhouette (docs/input-format.md, "Photo").

:func:`read_image` decodes and checks a photo (EXIF orientation applied, RGB out, the
alpha channel as the silhouette); :func:`estimate_silhouette` finds the object on a
plain background when the photo has no alpha.
"""

from __future__ import annotations

import logging
import math
from pathlib import Path

import numpy as np
from PIL import Image, ImageOps
from scipy import ndimage

from asset_pipeline.inputs.errors import InputError

log = logging.getLogger(__name__)

MIN_PHOTO_SIZE = 32

#: Alpha values at or above this count as the object (foreground) of a silhouette.
ALPHA_FOREGROUND = 128

#: A silhouette must hold at least this many pixels and this fraction of the photo
#: (the larger wins): 64 px is an 8x8 object, 0.1% is ~32x32 px in a 1 Mpx photo.
MIN_SILHOUETTE_PIXELS = 64
MIN_SILHOUETTE_FRACTION = 0.001

#: Plain-background estimate of a silhouette for photos without alpha: the border
#: band (px) whose colours are compared, the largest per-channel difference (0..255)
#: from the band's median colour a "uniform" border pixel may have, and the share of
#: band pixels that must be uniform.
BORDER_WIDTH = 2
BORDER_TOLERANCE = 16
BORDER_UNIFORM_FRACTION = 0.95
#: Background pixels differ from the background colour by at most
#: max(BACKGROUND_MIN_TOLERANCE, 2 x the 95th percentile of the border's differences).
BACKGROUND_MIN_TOLERANCE = 8
#: An estimate is trusted only when the background reached from the border, shrunk
#: by BACKGROUND_MIN_DEPTH x the shorter side, still covers MIN_BACKGROUND_FRACTION of
#: the photo: a background is deep somewhere, while a thin plain frame round a busy
#: picture (or a close-up that leaves only slivers of background) is not.
BACKGROUND_MIN_DEPTH = 0.04
MIN_BACKGROUND_FRACTION = 0.1
#: The silhouette comparison runs on a grid subsampled to at most this many pixels a
#: side (~8 ms for a 1024x1024 or a 4000x3000 photo).
SILHOUETTE_GRID = 256


def open_image(path: Path, what: str) -> Image.Image:
    try:
        img = Image.open(path)
        img.load()
    except FileNotFoundError as e:
        raise InputError(f"{path}: {what} not found") from e
    except (OSError, SyntaxError, ValueError, Image.DecompressionBombError) as e:
        raise InputError(f"{path}: unreadable or corrupt {what}: {e}") from e
    return img


def min_silhouette_pixels(height: int, width: int) -> int:
    """Fewest foreground pixels a silhouette of an (height, width) photo may have."""
    return max(MIN_SILHOUETTE_PIXELS, math.ceil(MIN_SILHOUETTE_FRACTION * height * width))


def read_image(path: str | Path) -> tuple[np.ndarray, np.ndarray | None]:
    """Decode a photo: ((H, W, 3) uint8 RGB, (H, W) uint8 alpha or None).

    The EXIF orientation of camera photos is applied. Grey and palette images are
    expanded to RGB; an alpha channel that is fully opaque carries no silhouette and
    is returned as None. Refused: photos smaller than MIN_PHOTO_SIZE px a side and
    photos whose alpha silhouette is (nearly) empty.
    """
    path = Path(path)
    img = open_image(path, "image")
    try:
        img = ImageOps.exif_transpose(img)
    except Exception as e:  # malformed EXIF must not sink a usable photo
        log.warning("%s: ignoring unreadable EXIF orientation: %s", path, e)
    if img.mode in ("I", "I;16", "I;16B", "I;16L", "F"):
        raise InputError(
            f"{path}: {img.mode} images are not supported; save the photo as 8-bit RGB"
        )
    w, h = img.size
    if w < MIN_PHOTO_SIZE or h < MIN_PHOTO_SIZE:
        raise InputError(
            f"{path}: photo is {w}x{h} px; at least {MIN_PHOTO_SIZE}x{MIN_PHOTO_SIZE} px are "
            "needed to see an object"
        )
    has_alpha = img.mode in ("RGBA", "RGBa", "LA", "La", "PA") or (
        img.mode == "P" and "transparency" in img.info
    )
    if has_alpha:
        rgba = np.asarray(img.convert("RGBA"))
        rgb, alpha = np.ascontiguousarray(rgba[..., :3]), np.ascontiguousarray(rgba[..., 3])
    else:
        rgb, alpha = np.asarray(img.convert("RGB")), None
    if alpha is not None:
        if bool((alpha == 255).all()):
            alpha = None
        else:
            _check_alpha(alpha, path)
    if alpha is None:
        _check_not_plain(rgb, path)
    return rgb.astype(np.uint8, copy=False), alpha


#: A photo whose colours (1st to 99th percentile, every channel) span less than this
#: is one plain colour: there is no object in it.
PLAIN_PHOTO_SPREAD = 8


def _check_not_plain(rgb: np.ndarray, path: Path) -> None:
    """Refuse an (H, W, 3) photo that is one plain colour (nothing to convert)."""
    stride = max(1, -(-max(rgb.shape[:2]) // SILHOUETTE_GRID))
    grid = rgb[::stride, ::stride].reshape(-1, 3)
    lo, hi = np.percentile(grid, [1, 99], axis=0)
    if float((hi - lo).max()) < PLAIN_PHOTO_SPREAD:
        raise InputError(
            f"{path}: the photo is one plain colour (RGB {np.median(grid, axis=0).astype(int).tolist()}"
            "); there is no object to convert"
        )


def _check_alpha(alpha: np.ndarray, path: Path) -> None:
    """Refuse an (H, W) uint8 alpha channel whose silhouette is (nearly) empty."""
    h, w = alpha.shape
    n = int(np.count_nonzero(alpha >= ALPHA_FOREGROUND))
    need = min_silhouette_pixels(h, w)
    if n < need:
        raise InputError(
            f"{path}: the photo's silhouette is empty: its alpha channel marks {n} px as the "
            f"object (alpha >= {ALPHA_FOREGROUND}), at least {need} are needed; remove the "
            "alpha channel (save as RGB) or paint the object opaque"
        )


def grid_stride(height: int, width: int) -> int:
    """Subsampling step that brings the longer side to at most SILHOUETTE_GRID px."""
    return max(1, math.ceil(max(height, width) / SILHOUETTE_GRID))


def plain_background(image: np.ndarray) -> tuple[np.ndarray, int] | None:
    """The background colour of a photo on a plain background, or None.

    ``image``: (H, W, 3) uint8. The colour is the median of the BORDER_WIDTH px
    border band; the background is plain when BORDER_UNIFORM_FRACTION of the band
    lies within BORDER_TOLERANCE (largest per-channel difference, 0..255) of it.
    Returns ((3,) int16 colour, tolerance), the tolerance (0..255) to use for
    telling background pixels apart: max(BACKGROUND_MIN_TOLERANCE, 2 x the band's
    95th-percentile difference), so that noisy (JPEG) backgrounds get more slack.
    """
    b = BORDER_WIDTH
    band = np.concatenate(
        [
            image[:b].reshape(-1, 3),
            image[-b:].reshape(-1, 3),
            image[b:-b, :b].reshape(-1, 3),
            image[b:-b, -b:].reshape(-1, 3),
        ]
    ).astype(np.int16)
    colour = np.median(band, axis=0).astype(np.int16)
    diff = np.abs(band - colour).max(axis=1)
    if np.count_nonzero(diff <= BORDER_TOLERANCE) < BORDER_UNIFORM_FRACTION * len(diff):
        return None
    tolerance = max(BACKGROUND_MIN_TOLERANCE, int(2 * np.percentile(diff, 95)))
    return colour, tolerance


def estimate_silhouette(image: np.ndarray, stride: int = 1) -> np.ndarray | None:
    """The object of a photo on a plain background, or None when it cannot be told.

    ``image``: (H, W, 3) uint8. Returns a (ceil(H / stride), ceil(W / stride)) bool
    mask on the grid ``image[::stride, ::stride]``: every pixel that is not part of
    the background, i.e. of a region of background-coloured pixels (see
    :func:`plain_background`) connected to the border. Holes of background colour
    inside the object thus count as object; a 3x3 opening drops specks of noise.
    None when the border is not plain (a busy background), when the background is
    too shallow to be one (see MIN_BACKGROUND_FRACTION), or when the object is
    smaller than :func:`min_silhouette_pixels`.
    """
    background = plain_background(image)
    if background is None:
        return None
    colour, tolerance = background
    grid = image[::stride, ::stride].astype(np.int16)
    near = np.abs(grid - colour).max(axis=2) <= tolerance
    labels, _ = ndimage.label(near)
    edge = np.unique(np.concatenate([labels[0], labels[-1], labels[:, 0], labels[:, -1]]))
    reached = np.isin(labels, edge[edge > 0])
    depth = max(1, round(BACKGROUND_MIN_DEPTH * min(reached.shape)))
    # Outside the image counts as background, so the band along the border shrinks only
    # from its inner side.
    deep = ndimage.binary_erosion(reached, iterations=depth, border_value=1)
    if np.count_nonzero(deep) < MIN_BACKGROUND_FRACTION * reached.size:
        return None
    silhouette = ndimage.binary_opening(~reached)
    h, w = image.shape[:2]
    if np.count_nonzero(silhouette) * stride * stride < min_silhouette_pixels(h, w):
        return None
    return silhouette

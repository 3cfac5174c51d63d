"""Random image backgrounds composited behind rendered objects (through the part mask)."""

from __future__ import annotations

import numpy as np
from PIL import Image

KINDS = ("plain", "gradient", "checker", "stripes", "noise")
# probability of each kind; plain colours are the most common
_WEIGHTS = np.array([0.4, 0.15, 0.15, 0.15, 0.15])


def _colour(rng: np.random.Generator) -> np.ndarray:
    return rng.uniform(0.0, 255.0, size=3)


def _two_colours(rng: np.random.Generator) -> tuple[np.ndarray, np.ndarray]:
    a = _colour(rng)
    b = np.clip(a + rng.normal(0.0, 60.0, size=3), 0, 255)
    return a, b


def random_background(rng: np.random.Generator, size: int) -> np.ndarray:
    """(size, size, 3) uint8: a plain colour or a procedural texture.

    Textures are a linear gradient, a rotated checkerboard, rotated stripes, or smooth
    value noise, each between two related random colours.
    """
    kind = KINDS[int(rng.choice(len(KINDS), p=_WEIGHTS))]
    if kind == "plain":
        img = np.broadcast_to(_colour(rng), (size, size, 3))
        return np.round(img).astype(np.uint8)
    a, b = _two_colours(rng)
    ys, xs = (np.mgrid[0:size, 0:size] + 0.5) / size  # (H, W) each, in [0, 1]
    theta = rng.uniform(0.0, np.pi)
    along = xs * np.cos(theta) + ys * np.sin(theta)
    across = -xs * np.sin(theta) + ys * np.cos(theta)
    if kind == "gradient":
        t = (along - along.min()) / max(float(np.ptp(along)), 1e-9)
    elif kind == "checker":
        cells = rng.uniform(3.0, 16.0)
        t = ((np.floor(along * cells) + np.floor(across * cells)) % 2).astype(float)
    elif kind == "stripes":
        cells = rng.uniform(3.0, 24.0)
        duty = rng.uniform(0.3, 0.7)
        t = ((along * cells) % 1.0 < duty).astype(float)
    else:  # noise: random grid upsampled bicubically, one or two octaves
        t = np.zeros((size, size))
        for octave, weight in ((int(rng.integers(3, 8)), 1.0), (int(rng.integers(12, 24)), 0.35)):
            grid = rng.random((octave, octave)).astype(np.float32)
            up = Image.fromarray(grid).resize((size, size), Image.Resampling.BICUBIC)
            t += weight * np.asarray(up, dtype=float)
        t = (t - t.min()) / max(float(np.ptp(t)), 1e-9)
    img = a[None, None, :] * (1.0 - t[..., None]) + b[None, None, :] * t[..., None]
    return np.clip(np.round(img), 0, 255).astype(np.uint8)

"""Seeded, recorded parameter sampling with train/test held-out sub-ranges.

Every object is drawn from a ``numpy.random.Generator`` seeded by a stable hash
(SHA-256) of ``(category, seed, split)``, so the same triple always gives the same
object on every machine and Python version. Each draw is recorded by name in
``ParamSampler.params`` (it ends up in the object's provenance).

A few parameters per category are *split* parameters (``SplitRange`` /
``SplitChoice``): ``split="test"`` draws them only from a held-out sub-range (or
held-out values) that ``split="train"`` never uses.
"""

from __future__ import annotations

import hashlib
from collections.abc import Sequence
from dataclasses import dataclass
from typing import Any

import numpy as np

SPLITS = ("train", "test")


def stable_seed(category: str, seed: int, split: str) -> int:
    """A 64-bit seed from SHA-256 of ``category:seed:split`` (independent of ``hash()``)."""
    digest = hashlib.sha256(f"{category}:{int(seed)}:{split}".encode()).digest()
    return int.from_bytes(digest[:8], "little")


@dataclass(frozen=True)
class SplitRange:
    """A float parameter over ``[lo, hi]`` with a held-out sub-interval ``[held_lo, held_hi]``.

    train draws uniformly from ``[lo, held_lo) U (held_hi, hi]``; test draws
    uniformly from ``[held_lo, held_hi]``.
    """

    lo: float
    hi: float
    held_lo: float
    held_hi: float

    def __post_init__(self) -> None:
        if not self.lo < self.held_lo < self.held_hi < self.hi:
            raise ValueError(f"held-out range must lie strictly inside the full range: {self}")

    def sample(self, rng: np.random.Generator, split: str) -> float:
        if split == "test":
            return float(rng.uniform(self.held_lo, self.held_hi))
        below, above = self.held_lo - self.lo, self.hi - self.held_hi
        u = float(rng.uniform(0.0, below + above))
        return self.lo + u if u < below else self.held_hi + (u - below)

    def held_out(self, value: float) -> bool:
        return self.held_lo <= value <= self.held_hi


@dataclass(frozen=True)
class SplitChoice:
    """An integer parameter: train picks from ``train``, test from the disjoint ``test``."""

    train: tuple[int, ...]
    test: tuple[int, ...]

    def __post_init__(self) -> None:
        if set(self.train) & set(self.test):
            raise ValueError(f"train and test values must be disjoint: {self}")

    def sample(self, rng: np.random.Generator, split: str) -> int:
        values = self.test if split == "test" else self.train
        return int(values[int(rng.integers(len(values)))])

    def held_out(self, value: int) -> bool:
        return value in self.test


class ParamSampler:
    """Draws named parameters from a seeded generator and records them in ``params``."""

    def __init__(self, category: str, seed: int, split: str) -> None:
        if split not in SPLITS:
            raise ValueError(f"split must be one of {SPLITS}, got {split!r}")
        self.split = split
        self.rng = np.random.default_rng(stable_seed(category, seed, split))
        self.params: dict[str, Any] = {}

    def _record(self, name: str, value: Any) -> Any:
        if name in self.params:
            raise KeyError(f"parameter {name!r} drawn twice")
        self.params[name] = list(value) if isinstance(value, tuple) else value  # JSON-shaped
        return value

    def uniform(self, name: str, lo: float, hi: float) -> float:
        """A float uniform in ``[lo, hi]``."""
        return self._record(name, float(self.rng.uniform(lo, hi)))

    def integer(self, name: str, lo: int, hi: int) -> int:
        """An integer uniform in ``[lo, hi]`` (both inclusive)."""
        return self._record(name, int(self.rng.integers(lo, hi + 1)))

    def choice(self, name: str, options: Sequence[Any], p: Sequence[float] | None = None) -> Any:
        """One of ``options`` (optionally weighted by ``p``)."""
        k = int(self.rng.choice(len(options), p=None if p is None else np.asarray(p) / np.sum(p)))
        return self._record(name, options[k])

    def flag(self, name: str, p: float) -> bool:
        """True with probability ``p``."""
        return self._record(name, bool(self.rng.uniform() < p))

    def split_param(self, name: str, spec: SplitRange | SplitChoice) -> Any:
        """A split-dependent parameter (held-out sub-range for ``split="test"``)."""
        return self._record(name, spec.sample(self.rng, self.split))

    def child_rng(self) -> np.random.Generator:
        """An independent generator for unrecorded detail (texture noise)."""
        return np.random.default_rng(int(self.rng.integers(2**63)))

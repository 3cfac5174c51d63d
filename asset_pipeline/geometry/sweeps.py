"""Exact swept volumes of boxes, as unions of convex hulls, and box-against-hull tests.

A movable part's collision boxes swept through its joint range cover the space the
part needs to move in. :func:`swept_hulls` returns that space as convex hulls: one
hull of each box at its lower and upper position for a prismatic joint; for a
revolute joint, hulls of each box at consecutive angles close enough that the arc
between them bulges at most ``sag`` beyond the chord. :class:`HullSet` tests
axis-aligned boxes against such hulls by the separating-axis theorem (the boxes'
axes, the hulls' face normals, and the cross products of box axes with hull edges):
exact for convex sets, vectorized over many boxes. Units: metres.
"""

from __future__ import annotations

import math
from collections.abc import Iterable
from dataclasses import dataclass

import numpy as np
from scipy.spatial import ConvexHull, QhullError

from generator.articulated import Joint

#: Largest distance (m) between a revolute arc and the chord that replaces it.
DEFAULT_SAG = 0.0005


def box_corners(lo: np.ndarray, hi: np.ndarray) -> np.ndarray:
    """(8, 3) corners of the axis-aligned box [lo, hi]."""
    return np.array(
        [[x, y, z] for x in (lo[0], hi[0]) for y in (lo[1], hi[1]) for z in (lo[2], hi[2])]
    )


def joint_samples(joint: Joint, radius: float, sag: float = DEFAULT_SAG) -> np.ndarray:
    """Joint values from lower to upper for hull sweeps: the ends for a prismatic joint;
    angles whose chords stay within ``sag`` of the arcs at ``radius`` (m) for revolute."""
    if joint.type == "prismatic" or radius <= 0:
        return np.array([joint.lower, joint.upper])
    step = 2.0 * math.acos(max(-1.0, 1.0 - sag / radius))
    n = max(1, math.ceil((joint.upper - joint.lower) / step))
    return np.linspace(joint.lower, joint.upper, n + 1)


@dataclass
class _Hull:
    lo: np.ndarray  # (3,) bounds, for a quick reject
    hi: np.ndarray
    axes: np.ndarray  # (K, 3) unit separating-axis candidates
    proj_min: np.ndarray  # (K,) the hull's projection onto each axis
    proj_max: np.ndarray


def _hull_of(points: np.ndarray) -> _Hull | None:
    try:
        h = ConvexHull(points)
    except (QhullError, ValueError):
        return None
    v = points[h.vertices]
    normals = h.equations[:, :3]
    edges = np.concatenate([points[h.simplices[:, [0, 1, 2]]] - points[h.simplices[:, [1, 2, 0]]]])
    edges = edges.reshape(-1, 3)
    crosses = np.cross(np.eye(3)[:, None, :], edges[None, :, :]).reshape(-1, 3)
    axes = np.concatenate([np.eye(3), normals, crosses])
    n = np.linalg.norm(axes, axis=1)
    axes = axes[n > 1e-9] / n[n > 1e-9, None]
    axes = np.unique(np.round(axes, 9), axis=0)
    proj = v @ axes.T
    return _Hull(v.min(axis=0), v.max(axis=0), axes, proj.min(axis=0), proj.max(axis=0))


class HullSet:
    """A union of convex hulls; boxes are tested against it with a margin.

    The hulls' data are stacked (axes padded by repeating a hull's first axis) so that a
    test of N boxes against H hulls and K axes is one (N, H, K) array computation.
    """

    def __init__(self) -> None:
        self.hulls: list[_Hull] = []
        self._stacked: tuple[np.ndarray, ...] | None = None

    def __len__(self) -> int:
        return len(self.hulls)

    def add(self, points: np.ndarray) -> None:
        """Add the convex hull of ``points`` (N, 3) (ignored when flat or degenerate)."""
        h = _hull_of(np.asarray(points, dtype=np.float64))
        if h is not None:
            self.hulls.append(h)
            self._stacked = None

    def add_box(self, lo: np.ndarray, hi: np.ndarray) -> None:
        self.add(box_corners(lo, hi))

    @classmethod
    def union(cls, sets: Iterable[HullSet]) -> HullSet:
        """A set of every hull of ``sets``."""
        out = cls()
        for s in sets:
            out.hulls.extend(s.hulls)
        return out

    def _stack(self) -> tuple[np.ndarray, ...]:
        if self._stacked is None:
            k = max(len(h.axes) for h in self.hulls)
            axes = np.empty((len(self.hulls), k, 3))
            pmin = np.empty((len(self.hulls), k))
            pmax = np.empty((len(self.hulls), k))
            for i, h in enumerate(self.hulls):
                n = len(h.axes)
                axes[i, :n], pmin[i, :n], pmax[i, :n] = h.axes, h.proj_min, h.proj_max
                axes[i, n:], pmin[i, n:], pmax[i, n:] = h.axes[0], h.proj_min[0], h.proj_max[0]
            lo = np.array([h.lo for h in self.hulls])
            hi = np.array([h.hi for h in self.hulls])
            self._stacked = (lo, hi, axes, pmin, pmax)
        return self._stacked

    def intersects(self, lo: np.ndarray, hi: np.ndarray, margin: float = 0.0) -> np.ndarray:
        """(N,) True where box [lo[i], hi[i]] (grown by ``margin``) meets any hull."""
        lo = np.atleast_2d(lo) - margin
        hi = np.atleast_2d(hi) + margin
        hit = np.zeros(len(lo), bool)
        if not self.hulls:
            return hit
        hlo, hhi, axes, pmin, pmax = self._stack()
        # candidate pairs: overlapping bounds
        near = np.all((lo[:, None] <= hhi[None]) & (hi[:, None] >= hlo[None]), axis=2)  # (N, H)
        bi, hj = np.nonzero(near)
        for start in range(0, len(bi), 4096):  # bounded memory: pairs x K axes at a time
            b, h = bi[start : start + 4096], hj[start : start + 4096]
            centre, half = 0.5 * (lo[b] + hi[b]), 0.5 * (hi[b] - lo[b])
            c = np.einsum("pkd,pd->pk", axes[h], centre)
            r = np.einsum("pkd,pd->pk", np.abs(axes[h]), half)
            separated = ((c + r) < pmin[h]) | ((c - r) > pmax[h])
            hit[b[~separated.any(axis=1)]] = True
        return hit


def swept_hulls(
    joint: Joint, boxes: list[np.ndarray], hulls: HullSet, sag: float = DEFAULT_SAG
) -> None:
    """Add to ``hulls`` the space ``boxes`` ((2, 3) bounds, object frame at rest) sweep
    through over the joint's range (see the module docstring)."""
    for b in boxes:
        corners = box_corners(b[0], b[1])
        radius = 0.0
        if joint.type == "revolute":
            radius = float(
                np.linalg.norm(np.cross(corners - joint.origin, joint.axis), axis=1).max()
            )
        qs = joint_samples(joint, radius, sag)
        posed = []
        for q in qs:
            T = joint.transform(float(q))
            posed.append(corners @ T[:3, :3].T + T[:3, 3])
        for a, c in zip(posed[:-1], posed[1:], strict=True):
            hulls.add(np.concatenate([a, c]))

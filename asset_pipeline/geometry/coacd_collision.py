"""Convex collision pieces per part, in the object frame.

- A part with ``primitives`` (procedural objects) gets exactly those solids as its
  pieces: a box is its 8 corners, a cylinder a prism of at most 32 sides. No
  decomposition, no growth: sibling drawers with millimetre gaps stay apart.
- Any other part is decomposed by CoACD, run in a child process with a timeout
  (CoACD can abort or crash on some inputs) and cached on disk, keyed by a hash of
  the mesh arrays, the parameters and the CoACD version (cache folder:
  ``$PACT_CACHE_DIR`` or ``~/.cache/pact/coacd``). On timeout or crash the part's
  convex hull is used instead (logged as a warning, not cached).

Every piece is a convex hull with 4..255 vertices (PhysX's limit) and positive
volume; larger hulls are reduced to the hull of a farthest-point subset of their
vertices. Units and frame are those of the input (metres, object frame, after
``asset_pipeline.geometry.metric.to_metric``).
"""

from __future__ import annotations

import hashlib
import importlib.metadata
import io
import json
import logging
import os
import subprocess
import sys
import tempfile
from dataclasses import asdict, dataclass
from pathlib import Path

import numpy as np
import trimesh

from generator.articulated import Part, Primitive
from generator.atomic_files import atomic_write_bytes

log = logging.getLogger(__name__)

MAX_HULL_VERTICES = 255
#: Pieces smaller than this (m^3) are dropped as degenerate (1 mm^3).
MIN_PIECE_VOLUME = 1e-9
CYLINDER_SIDES = 32


@dataclass(frozen=True)
class CoacdParams:
    """Parameters passed to ``coacd.run_coacd`` (see its documentation); part of the cache key."""

    threshold: float = 0.05
    max_convex_hull: int = -1
    preprocess_mode: str = "auto"
    preprocess_resolution: int = 50
    resolution: int = 2000
    mcts_nodes: int = 20
    mcts_iterations: int = 150
    mcts_max_depth: int = 3
    max_ch_vertex: int = 256
    seed: int = 0


class CoacdFailed(RuntimeError):
    """CoACD timed out, crashed or returned nothing usable."""


# --------------------------------------------------------------------------- pieces


def farthest_point_subset(points: np.ndarray, k: int) -> np.ndarray:
    """Indices (k,) of a greedy farthest-point subset of ``points`` (N, 3); deterministic.

    Starts at the point farthest from the centroid.
    """
    pts = np.asarray(points, dtype=float)
    n = len(pts)
    if k >= n:
        return np.arange(n)
    first = int(np.argmax(np.linalg.norm(pts - pts.mean(axis=0), axis=1)))
    chosen = [first]
    dist = np.linalg.norm(pts - pts[first], axis=1)
    for _ in range(k - 1):
        i = int(np.argmax(dist))
        chosen.append(i)
        dist = np.minimum(dist, np.linalg.norm(pts - pts[i], axis=1))
    return np.array(sorted(chosen))


def convex_piece(
    points: np.ndarray,
    max_vertices: int = MAX_HULL_VERTICES,
    min_volume: float = MIN_PIECE_VOLUME,
) -> trimesh.Trimesh | None:
    """Convex hull of ``points`` (N, 3) with 4..``max_vertices`` vertices, or None if degenerate.

    A hull with too many vertices is replaced by the hull of a farthest-point subset
    of its vertices (slightly smaller, never larger than the original hull).
    """
    pts = np.asarray(points, dtype=float)
    if len(pts) < 4 or not np.isfinite(pts).all():
        return None
    try:
        with np.errstate(invalid="ignore", divide="ignore"):  # flat input: zero volume
            hull = trimesh.convex.convex_hull(pts)
            while len(hull.vertices) > max_vertices:
                idx = farthest_point_subset(hull.vertices, max_vertices)
                hull = trimesh.convex.convex_hull(hull.vertices[idx])
    except Exception as e:  # noqa: BLE001 - qhull raises on flat / coplanar input
        log.debug("degenerate hull of %d points: %s", len(pts), e)
        return None
    if len(hull.vertices) < 4:
        return None
    with np.errstate(invalid="ignore", divide="ignore"):  # flat hulls divide by zero volume
        if not (hull.volume >= min_volume and hull.is_volume):
            return None
    return hull


def primitive_pieces(primitives: list[Primitive]) -> list[trimesh.Trimesh]:
    """The exact convex solids of ``primitives`` (object frame): boxes 8 vertices, cylinders prisms."""
    pieces = []
    for prim in primitives:
        mesh = prim.to_mesh(sections=CYLINDER_SIDES)
        piece = convex_piece(mesh.vertices)
        if piece is None:
            log.warning(
                "dropping degenerate %s primitive of size %s", prim.kind, prim.size.tolist()
            )
            continue
        pieces.append(piece)
    return pieces


def hull_pieces(mesh: trimesh.Trimesh) -> list[trimesh.Trimesh]:
    """The convex hull of ``mesh`` as the only piece (empty when the mesh is flat)."""
    piece = convex_piece(mesh.vertices)
    return [] if piece is None else [piece]


# --------------------------------------------------------------------------- CoACD + cache


def default_cache_dir() -> Path:
    """``$PACT_CACHE_DIR`` if set, else ``~/.cache/pact/coacd``."""
    env = os.environ.get("PACT_CACHE_DIR")
    return Path(env) if env else Path.home() / ".cache" / "pact" / "coacd"


def _coacd_version() -> str:
    try:
        return importlib.metadata.version("coacd")
    except importlib.metadata.PackageNotFoundError:
        return "unknown"


def cache_key(vertices: np.ndarray, faces: np.ndarray, params: CoacdParams) -> str:
    """Hex sha256 of the mesh arrays (float64 / int64, C order), parameters and CoACD version."""
    h = hashlib.sha256()
    h.update(np.ascontiguousarray(vertices, dtype=np.float64).tobytes())
    h.update(np.ascontiguousarray(faces, dtype=np.int64).tobytes())
    h.update(json.dumps(asdict(params), sort_keys=True).encode())
    h.update(_coacd_version().encode())
    return h.hexdigest()


def _pack(parts: list[tuple[np.ndarray, np.ndarray]]) -> bytes:
    buf = io.BytesIO()
    np.savez(
        buf,
        vertices=np.concatenate([v for v, _ in parts]) if parts else np.zeros((0, 3)),
        faces=np.concatenate([f for _, f in parts]) if parts else np.zeros((0, 3), dtype=np.int64),
        nv=np.array([len(v) for v, _ in parts], dtype=np.int64),
        nf=np.array([len(f) for _, f in parts], dtype=np.int64),
    )
    return buf.getvalue()


def _unpack(data: bytes | Path) -> list[tuple[np.ndarray, np.ndarray]]:
    src = data if isinstance(data, Path) else io.BytesIO(data)
    with np.load(src) as z:
        v, f, nv, nf = z["vertices"], z["faces"], z["nv"], z["nf"]
    out = []
    vo = np.concatenate([[0], np.cumsum(nv)])
    fo = np.concatenate([[0], np.cumsum(nf)])
    for i in range(len(nv)):
        out.append((v[vo[i] : vo[i + 1]], f[fo[i] : fo[i + 1]]))
    return out


def _run_coacd_subprocess(
    vertices: np.ndarray, faces: np.ndarray, params: CoacdParams, timeout: float
) -> list[tuple[np.ndarray, np.ndarray]]:
    """Run CoACD in a child Python process; raise CoacdFailed on timeout, crash or no output."""
    with tempfile.TemporaryDirectory(prefix="pact-coacd-") as tmp:
        src, dst = Path(tmp) / "in.npz", Path(tmp) / "out.npz"
        np.savez(src, vertices=vertices, faces=faces)
        cmd = [sys.executable, "-m", "asset_pipeline.geometry.coacd_collision", str(src), str(dst)]
        cmd.append(json.dumps(asdict(params)))
        env = dict(os.environ)
        root = str(Path(__file__).resolve().parents[2])
        env["PYTHONPATH"] = (
            os.pathsep.join([root, env["PYTHONPATH"]]) if env.get("PYTHONPATH") else root
        )
        try:
            proc = subprocess.run(cmd, capture_output=True, timeout=timeout, env=env, check=False)
        except subprocess.TimeoutExpired as e:
            raise CoacdFailed(f"CoACD timed out after {timeout:g} s") from e
        if proc.returncode != 0 or not dst.is_file():
            tail = proc.stderr.decode(errors="replace").strip().splitlines()[-3:]
            raise CoacdFailed(f"CoACD exited with code {proc.returncode}: {' | '.join(tail)}")
        parts = _unpack(dst)
    if not parts:
        raise CoacdFailed("CoACD returned no parts")
    return parts


def coacd_pieces(
    mesh: trimesh.Trimesh,
    params: CoacdParams = CoacdParams(),
    *,
    timeout: float = 300.0,
    cache_dir: Path | None = None,
) -> list[trimesh.Trimesh]:
    """Convex decomposition of ``mesh`` (same frame and units) by CoACD, cached on disk.

    Raises CoacdFailed when CoACD times out, crashes or gives no usable piece; the
    caller decides the fallback (:func:`part_pieces` uses the convex hull).
    """
    cache_dir = default_cache_dir() if cache_dir is None else Path(cache_dir)
    v = np.ascontiguousarray(mesh.vertices, dtype=np.float64)
    f = np.ascontiguousarray(mesh.faces, dtype=np.int64)
    key = cache_key(v, f, params)
    path = cache_dir / f"{key}.npz"
    raw = None
    if path.is_file():
        try:
            raw = _unpack(path)
            log.debug("CoACD cache hit %s", path)
        except Exception as e:  # noqa: BLE001 - a damaged cache entry is recomputed
            log.warning("ignoring unreadable CoACD cache entry %s: %s", path, e)
    if raw is None:
        raw = _run_coacd_subprocess(v, f, params, timeout)
        atomic_write_bytes(path, _pack(raw))
    pieces = [p for p in (convex_piece(pv) for pv, _ in raw) if p is not None]
    if not pieces:
        raise CoacdFailed("every CoACD piece was degenerate")
    return pieces


def part_pieces(
    part: Part,
    params: CoacdParams = CoacdParams(),
    *,
    timeout: float = 300.0,
    cache_dir: Path | None = None,
) -> list[trimesh.Trimesh]:
    """Convex pieces of one part in the object frame (see the module docstring)."""
    if part.primitives:
        pieces = primitive_pieces(part.primitives)
        if pieces:
            return pieces
        log.warning("part %s: every primitive was degenerate; decomposing its mesh", part.name)
    try:
        return coacd_pieces(part.mesh, params, timeout=timeout, cache_dir=cache_dir)
    except CoacdFailed as e:
        log.warning("part %s: %s; falling back to its convex hull", part.name, e)
    pieces = hull_pieces(part.mesh)
    if not pieces:
        raise CoacdFailed(f"part {part.name}: no convex piece (the mesh is flat or empty)")
    return pieces


# --------------------------------------------------------------------------- child process


def _worker(src: str, dst: str, params_json: str) -> None:
    import coacd

    coacd.set_log_level("error")
    with np.load(src) as z:
        mesh = coacd.Mesh(z["vertices"], z["faces"])
    result = coacd.run_coacd(mesh, **json.loads(params_json))
    parts = [(np.asarray(v, dtype=np.float64), np.asarray(f, dtype=np.int64)) for v, f in result]
    Path(dst).write_bytes(_pack(parts))


if __name__ == "__main__":
    _worker(*sys.argv[1:4])

"""asset_pipeline.geometry.coacd_collision: exact primitive pieces, bounded hulls, cached CoACD, fallbacks."""

from __future__ import annotations

import numpy as np
import pytest
import trimesh

from asset_pipeline.geometry import coacd_collision as collision
from asset_pipeline.geometry.coacd_collision import (
    MAX_HULL_VERTICES,
    CoacdFailed,
    CoacdParams,
    cache_key,
    coacd_pieces,
    convex_piece,
    farthest_point_subset,
    part_pieces,
    primitive_pieces,
)
from generator.articulated import Part, Primitive


def _l_shape() -> trimesh.Trimesh:
    """A small watertight L (two unioned boxes, 36 faces)."""
    a = trimesh.creation.box([0.4, 0.1, 0.1])
    b = trimesh.creation.box([0.1, 0.1, 0.4])
    b.apply_translation([0.15, 0, 0.15])
    return trimesh.boolean.union([a, b], engine="manifold")


def test_primitive_pieces_are_exact():
    R = trimesh.transformations.rotation_matrix(0.3, [0, 0, 1])
    R[:3, 3] = [1.0, 2.0, 0.5]
    box = Primitive("box", [0.2, 0.4, 0.6], R)
    cyl = Primitive("cylinder", [0.05, 0.3], np.eye(4))
    pb, pc = primitive_pieces([box, cyl])
    assert len(pb.vertices) == 8
    assert pb.volume == pytest.approx(0.2 * 0.4 * 0.6)
    np.testing.assert_allclose(pb.centroid, [1.0, 2.0, 0.5], atol=1e-9)
    assert 4 <= len(pc.vertices) <= 64  # a prism of at most 32 sides
    assert pc.volume == pytest.approx(np.pi * 0.05**2 * 0.3, rel=0.02)
    assert pc.volume <= np.pi * 0.05**2 * 0.3  # inscribed prism, never grows


def test_convex_piece_limits_vertices_and_rejects_flat():
    sphere = trimesh.creation.icosphere(subdivisions=4, radius=0.2)  # 2562 hull vertices
    piece = convex_piece(sphere.vertices)
    assert 4 <= len(piece.vertices) <= MAX_HULL_VERTICES
    assert piece.is_volume and piece.volume > 0.9 * sphere.volume
    assert piece.volume <= sphere.volume + 1e-12
    flat = np.c_[np.random.default_rng(0).random((50, 2)), np.zeros(50)]
    assert convex_piece(flat) is None
    assert convex_piece(np.zeros((3, 3))) is None


def test_farthest_point_subset_spreads():
    pts = np.array([[0, 0, 0], [0.01, 0, 0], [1, 0, 0], [0, 1, 0], [0.5, 0.5, 0]], float)
    idx = farthest_point_subset(pts, 3)
    assert len(idx) == 3 and {2, 3} <= set(idx.tolist())


def test_coacd_cache_hit_skips_the_subprocess(tmp_path, monkeypatch):
    """Cache mechanics with a stand-in for the CoACD child process (the real CoACD run,
    and its cached re-run, are exercised once in tests/test_build.py)."""
    calls = []

    def fake_coacd(vertices, faces, params, timeout):
        calls.append(params)
        a = trimesh.creation.box([0.4, 0.1, 0.1])
        b = trimesh.creation.box([0.1, 0.1, 0.4])
        b.apply_translation([0.15, 0, 0.15])
        return [(a.vertices, a.faces), (b.vertices, b.faces)]

    monkeypatch.setattr(collision, "_run_coacd_subprocess", fake_coacd)
    mesh = _l_shape()
    pieces = coacd_pieces(mesh, cache_dir=tmp_path)
    assert len(calls) == 1 and len(pieces) == 2
    key = cache_key(mesh.vertices, mesh.faces, CoacdParams())
    assert (tmp_path / f"{key}.npz").is_file()
    again = coacd_pieces(mesh, cache_dir=tmp_path)
    assert len(calls) == 1  # served from the cache
    for p, q in zip(pieces, again, strict=True):
        np.testing.assert_allclose(p.vertices, q.vertices)
    # other parameters or another mesh -> another key -> CoACD runs again
    assert cache_key(mesh.vertices, mesh.faces, CoacdParams(threshold=0.1)) != key
    coacd_pieces(mesh, CoacdParams(threshold=0.1), cache_dir=tmp_path)
    assert len(calls) == 2
    # a damaged cache entry is recomputed, not trusted
    (tmp_path / f"{key}.npz").write_bytes(b"garbage")
    coacd_pieces(mesh, cache_dir=tmp_path)
    assert len(calls) == 3


def test_timeout_falls_back_to_hull(tmp_path, caplog):
    part = Part("lid_0", "lid", _l_shape())
    with caplog.at_level("WARNING"):
        pieces = part_pieces(part, cache_dir=tmp_path, timeout=0.01)
    assert len(pieces) == 1
    assert pieces[0].volume == pytest.approx(part.mesh.convex_hull.volume)
    assert "timed out" in caplog.text and "convex hull" in caplog.text
    assert not list(tmp_path.glob("*.npz"))  # failures are not cached


def test_crash_falls_back_to_hull(tmp_path, monkeypatch, caplog):
    def crash(*args, **kwargs):
        raise CoacdFailed("CoACD exited with code -6: abort")

    monkeypatch.setattr(collision, "_run_coacd_subprocess", crash)
    with caplog.at_level("WARNING"):
        pieces = part_pieces(Part("x", "lid", _l_shape()), cache_dir=tmp_path)
    assert len(pieces) == 1 and "code -6" in caplog.text


def test_parts_with_primitives_skip_coacd(tmp_path, monkeypatch):
    def boom(*args, **kwargs):
        raise AssertionError("CoACD must not run for a part with primitives")

    monkeypatch.setattr(collision, "_run_coacd_subprocess", boom)
    prims = [
        Primitive("box", [0.1, 0.1, 0.1], np.eye(4)),
        Primitive("box", [0.3, 0.1, 0.1], np.eye(4)),
    ]
    part = Part("drawer_0", "drawer", trimesh.creation.box([0.3, 0.1, 0.1]), primitives=prims)
    assert len(part_pieces(part, cache_dir=tmp_path)) == 2

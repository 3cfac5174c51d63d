"""The object model validates itself and bundles round-trip exactly."""

from __future__ import annotations

import json
import math

import numpy as np
import pytest
import trimesh
from PIL import Image

from generator.articulated import (
    ArticulatedObject,
    Handle,
    Joint,
    ObjectModelError,
    Part,
    Primitive,
)
from generator.bundle import find_bundles, load_bundle, save_bundle


def _box(extents, centre, rgba) -> trimesh.Trimesh:
    m = trimesh.creation.box(extents=extents)
    m.apply_translation(centre)
    m.visual.vertex_colors = rgba
    return m


def make_object() -> ArticulatedObject:
    base = _box([0.5, 0.6, 0.8], [0, 0, 0.4], [120, 80, 40, 255])
    drawer = _box([0.02, 0.5, 0.2], [0.26, 0, 0.6], [30, 60, 200, 255])
    door = _box([0.02, 0.5, 0.35], [0.26, 0, 0.2], [30, 160, 60, 255])
    uv = (door.vertices[:, 1:] - door.vertices[:, 1:].min(0)) / np.ptp(door.vertices[:, 1:], 0)
    tex = Image.fromarray((np.arange(8 * 8 * 3).reshape(8, 8, 3) * 3 % 255).astype(np.uint8))
    door.visual = trimesh.visual.TextureVisuals(uv=uv, image=tex)
    return ArticulatedObject(
        parts=[
            Part("base", "base", base, primitives=[Primitive("box", [0.5, 0.6, 0.8])]),
            Part(
                "drawer_0",
                "drawer",
                drawer,
                Joint("prismatic", [0.25, 0, 0.6], [1, 0, 0], 0.0, 0.35),
                handle=Handle([0.28, 0, 0.6], [0, 1, 0], "bar"),
            ),
            Part(
                "door_0",
                "door",
                door,
                Joint("revolute", [0.27, 0.25, 0.2], [0, 0, 1], 0.0, math.pi / 2),
                material="metal",
            ),
        ],
        category="cabinet",
        scale=1.0,
        provenance={"generator": "test", "seed": 3},
    )


def test_round_trip_is_exact(tmp_path):
    obj = make_object()
    save_bundle(obj, tmp_path / "a")
    back = load_bundle(tmp_path / "a")
    assert back.to_json() == obj.to_json()
    for p, q in zip(obj.parts, back.parts, strict=True):
        assert np.array_equal(p.mesh.vertices, q.mesh.vertices)
        assert np.array_equal(p.mesh.faces, q.mesh.faces)
        assert p.mesh.visual.kind == q.mesh.visual.kind
    assert np.array_equal(
        obj.part("drawer_0").mesh.visual.vertex_colors,
        back.part("drawer_0").mesh.visual.vertex_colors,
    )
    d0, d1 = obj.part("door_0").mesh.visual, back.part("door_0").mesh.visual
    assert np.array_equal(d0.uv, d1.uv)
    img0 = np.asarray(d0.material.image.convert("RGB"))
    img1 = np.asarray(d1.material.baseColorTexture.convert("RGB"))
    assert np.array_equal(img0, img1)
    # A second round trip changes nothing.
    save_bundle(back, tmp_path / "b")
    again = load_bundle(tmp_path / "b")
    assert (tmp_path / "a/object.json").read_text() == (tmp_path / "b/object.json").read_text()
    for p, q in zip(back.parts, again.parts, strict=True):
        assert np.array_equal(p.mesh.vertices, q.mesh.vertices)
        assert np.array_equal(p.mesh.faces, q.mesh.faces)


def test_joint_transform_moves_parts_as_expected():
    obj = make_object()
    drawer = obj.part("drawer_0")
    moved = drawer.posed_mesh(0.3)
    assert np.allclose(moved.vertices - drawer.mesh.vertices, [0.3, 0, 0])
    door = obj.part("door_0")
    # +90 degrees about +z through the hinge at y=0.25: the free edge at y=-0.25 swings to +x.
    free_edge = np.array([0.27, -0.25, 0.2])
    T = door.joint.transform(math.pi / 2)
    p = T[:3, :3] @ free_edge + T[:3, 3]
    assert np.allclose(p, [0.27 + 0.5, 0.25, 0.2])


@pytest.mark.parametrize(
    "mutate, field",
    [
        (lambda o: setattr(o.parts[1].joint, "axis", np.array([2.0, 0, 0])), "joint.axis"),
        (lambda o: setattr(o.parts[1].joint, "axis", np.array([np.nan, 0, 0])), "joint.axis"),
        (lambda o: setattr(o.parts[1].joint, "lower", 0.5), "joint.lower/upper"),
        (lambda o: setattr(o.parts[2].joint, "upper", math.inf), "joint.lower/upper"),
        (lambda o: setattr(o.parts[1].joint, "type", "spherical"), "joint.type"),
        (lambda o: setattr(o.parts[1].joint, "parent", "nowhere"), "joint.parent"),
        (lambda o: setattr(o.parts[2], "name", "drawer_0"), "unique"),
        (lambda o: setattr(o.parts[1], "joint", None), "exactly one base"),
        (lambda o: setattr(o, "scale", -1.0), "scale"),
    ],
)
def test_validation_names_the_field(mutate, field):
    obj = make_object()
    mutate(obj)
    with pytest.raises(ObjectModelError, match="mything/object.json") as e:
        obj.validate("mything/object.json")
    assert field in str(e.value)


def test_load_errors_name_file_and_field(tmp_path):
    obj = make_object()
    d = save_bundle(obj, tmp_path / "x")
    meta = json.loads((d / "object.json").read_text())

    (d / "object.json").write_text("{not json")
    with pytest.raises(ObjectModelError, match=r"object.json: not valid JSON"):
        load_bundle(d)

    bad = json.loads(json.dumps(meta))
    bad["parts"][1]["joint"]["axis"] = [0, 0, 3]
    (d / "object.json").write_text(json.dumps(bad))
    with pytest.raises(
        ObjectModelError, match=r"parts\[1\] \(drawer_0\)\.joint\.axis: must be a unit"
    ):
        load_bundle(d)

    bad = json.loads(json.dumps(meta))
    bad["parts"][2]["joint"]["lower"], bad["parts"][2]["joint"]["upper"] = 1.0, 0.0
    (d / "object.json").write_text(json.dumps(bad))
    with pytest.raises(ObjectModelError, match=r"door_0\)\.joint\.lower/upper"):
        load_bundle(d)

    bad = json.loads(json.dumps(meta))
    bad["version"] = 99
    (d / "object.json").write_text(json.dumps(bad))
    with pytest.raises(ObjectModelError, match="version"):
        load_bundle(d)

    (d / "object.json").write_text(json.dumps(meta))
    (d / "parts/door_0.glb").unlink()
    with pytest.raises(ObjectModelError, match=r"parts/door_0.glb not found"):
        load_bundle(d)

    (d / "parts/door_0.glb").write_bytes(b"garbage")
    with pytest.raises(ObjectModelError, match=r"door_0.glb: cannot read"):
        load_bundle(d)


def test_find_bundles(tmp_path):
    obj = make_object()
    save_bundle(obj, tmp_path / "b")
    save_bundle(obj, tmp_path / "a")
    (tmp_path / "not_a_bundle").mkdir()
    assert [p.name for p in find_bundles(tmp_path)] == ["a", "b"]
    assert find_bundles(tmp_path / "a") == [tmp_path / "a"]
    with pytest.raises(ObjectModelError):
        find_bundles(tmp_path / "missing")

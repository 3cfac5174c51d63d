"""``asset.json``: what URDF cannot say (category, semantics, materials, colours, handles,
bounds, metric scale; schema ``pact.asset`` v1), its one writer and its one reader.
"""

from __future__ import annotations

import json
from pathlib import Path
from typing import Any

import numpy as np

from asset_pipeline.assets.built_asset import HANDLE_KINDS, BuiltAsset, Handle
from asset_pipeline.assets.layout import ASSET_SCHEMA, ASSET_VERSION, AssetFormatError
from asset_pipeline.assets.xml_text import rounded

# --------------------------------------------------------------------------- asset.json


def asset_json_document(asset: BuiltAsset) -> dict[str, Any]:
    """The ``asset.json`` document (schema ``pact.asset`` v1) of ``asset``.

    Joint origins and axes, and handle positions, are given in the object frame at
    rest (``position_link`` in the part's link frame), for readers without a URDF
    parser; :func:`load_asset` takes the joints from the URDF.
    """
    rest = asset.link_poses()
    links = [
        {
            "name": link.name,
            "semantic": link.semantic,
            "mass": None if link.inertial is None else round(link.inertial.mass, 9),
            "material": link.material,
            "visual": link.visuals[0].filename if link.visuals else None,
            "collision": [p.filename for p in link.collisions],
            "rgba": rounded(link.rgba),
        }
        for link in asset.links
    ]
    joints = []
    for j in asset.joints:
        frame = rest.get(j.parent, np.eye(4)) @ j.origin
        joints.append(
            {
                "name": j.name,
                "parent": j.parent,
                "child": j.child,
                "type": j.type,
                "origin": rounded(frame[:3, 3]),
                "axis": rounded(frame[:3, :3] @ j.unit_axis),
                "lower": round(j.lower, 9),
                "upper": round(j.upper, 9),
                "damping": j.physics.damping,
                "friction": j.physics.friction,
                "effort": j.physics.effort,
                "velocity": j.physics.velocity,
            }
        )
    handles = {}
    for part, h in asset.handles.items():
        T = rest.get(part, np.eye(4))
        handles[part] = {
            "position": rounded(T[:3, :3] @ h.position_link + T[:3, 3]),
            "position_link": rounded(h.position_link),
            "axis": rounded(h.axis),
            "kind": h.kind,
        }
    bounds = asset.bounds if asset.bounds is not None else np.zeros((2, 3))
    return {
        "schema": ASSET_SCHEMA,
        "version": ASSET_VERSION,
        "id": asset.id,
        "category": asset.category,
        "metric_scale": asset.metric_scale,
        "bounds": [rounded(bounds[0]), rounded(bounds[1])],
        "links": links,
        "joints": joints,
        "handles": handles,
        "provenance": asset.provenance,
    }


def _vec3(v: Any, where: str, problems: list[str]) -> np.ndarray | None:
    try:
        a = np.asarray(v, dtype=float).reshape(-1)
    except (TypeError, ValueError):
        a = np.zeros(0)
    if a.shape != (3,) or not np.isfinite(a).all():
        problems.append(f"{where}: expected 3 finite numbers, got {v!r}")
        return None
    return a


def read_asset_json(path: Path) -> dict[str, Any]:
    """The checked ``asset.json`` document; raises :class:`AssetFormatError`."""
    try:
        doc = json.loads(path.read_text(encoding="utf-8"))
    except FileNotFoundError as e:
        raise AssetFormatError(path, ["not found (run `pact build` first)"]) from e
    except (OSError, json.JSONDecodeError, UnicodeDecodeError) as e:
        raise AssetFormatError(path, [f"not valid JSON: {e}"]) from e
    if not isinstance(doc, dict):
        raise AssetFormatError(path, ["the top level must be a JSON object"])
    if doc.get("schema", ASSET_SCHEMA) != ASSET_SCHEMA:
        raise AssetFormatError(path, [f"schema {doc.get('schema')!r} is not {ASSET_SCHEMA!r}"])
    if doc.get("version", ASSET_VERSION) != ASSET_VERSION:
        raise AssetFormatError(
            path, [f"version {doc.get('version')!r}: this pact reads version {ASSET_VERSION}"]
        )
    for key, kind in (("links", list), ("joints", list), ("handles", dict)):
        if not isinstance(doc.get(key, kind()), kind):
            raise AssetFormatError(path, [f"{key}: must be a {kind.__name__}"])
    return doc


def apply_metadata(asset: BuiltAsset, doc: dict[str, Any], path: Path) -> None:
    """Fill ``asset``'s identity, link semantics and handles from an asset.json document."""
    problems: list[str] = []
    asset.id = str(doc.get("id", asset.id))
    asset.category = str(doc.get("category", asset.category))
    scale = doc.get("metric_scale", 1.0)
    if isinstance(scale, bool) or not isinstance(scale, (int, float)) or not scale > 0:
        problems.append(f"metric_scale: must be a positive number, got {scale!r}")
    else:
        asset.metric_scale = float(scale)
    b = doc.get("bounds")
    if b is not None:
        lo = _vec3(b[0] if isinstance(b, list) and len(b) == 2 else None, "bounds", problems)
        hi = _vec3(b[1] if isinstance(b, list) and len(b) == 2 else None, "bounds", problems)
        if lo is not None and hi is not None:
            asset.bounds = np.stack([lo, hi])
    provenance = doc.get("provenance", {})
    if isinstance(provenance, dict):
        asset.provenance = dict(provenance)
    else:
        problems.append(f"provenance: must be an object, got {type(provenance).__name__}")
    names = {k.name: k for k in asset.links}
    for i, d in enumerate(doc.get("links", [])):
        if not isinstance(d, dict) or d.get("name") not in names:
            continue
        link = names[d["name"]]
        link.semantic = str(d.get("semantic", link.semantic))
        link.material = str(d.get("material", link.material))
        if "rgba" in d:
            try:
                rgba = np.asarray(d["rgba"], dtype=float).reshape(4)
            except (TypeError, ValueError):
                problems.append(f"links[{i}].rgba: expected 4 numbers, got {d['rgba']!r}")
            else:
                link.rgba = rgba
    for part, h in doc.get("handles", {}).items():
        where = f"handles[{part}]"
        if part not in names:
            problems.append(f"{where}: no link named {part!r} in the URDF")
            continue
        if not isinstance(h, dict):
            problems.append(f"{where}: must be an object")
            continue
        pos = _vec3(h.get("position_link"), f"{where}.position_link", problems)
        axis = _vec3(h.get("axis", [0, 0, 1]), f"{where}.axis", problems)
        kind = str(h.get("kind", "none"))
        if kind not in HANDLE_KINDS:
            problems.append(f"{where}.kind: {kind!r} is not one of {list(HANDLE_KINDS)}")
        if pos is not None and axis is not None:
            asset.handles[part] = Handle(position_link=pos, axis=axis, kind=kind)
    if problems:
        raise AssetFormatError(path, problems)

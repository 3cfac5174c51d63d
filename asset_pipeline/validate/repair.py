"""Automatic repairs of a built asset, driven by failed validation checks.

:func:`plan_and_apply` maps failed checks (:mod:`asset_pipeline.validate`) to
repairs, edits the built asset and returns one :class:`RepairRecord` per edit
(what, on which joint or link, before and after). Validation re-runs every check
after each round. Repairs, by the check that triggers them:

``hinge_on_part``      project the revolute origin onto the closest point of the part's
                       AABB surface (PAct's post-processing); the part's link-frame
                       geometry moves by the opposite amount so that the part stays put
``opens_outward``      flip the joint axis (the part opened into the base)
``drawer_engaged``     shorten the prismatic range so that ``ENGAGED_TARGET`` of the part's
                       length stays inside the base at the upper limit
``rest_penetration``   shrink the overlapping convex pieces of the movable part(s) along
                       the contact normal, about their centroid
``rest_drift``         raise the joint's damping and friction

At most one joint-level repair per joint per round (the first in the order
above), because each changes what the later checks measure. Everything else
(reversed limits, zero mass, uncookable pieces, a jammed drive, ...) is not
repairable and is reported with its reason.

Edits touch ``model.urdf``, ``collision/*.obj``, ``visual/*`` (origin projection
only), ``model.xml`` and ``asset.json``. All new contents are prepared first, then
each file is written atomically (temporary name + rename), mesh files first and
``asset.json`` last.
"""

from __future__ import annotations

import json
import logging
import xml.etree.ElementTree as ET
from pathlib import Path
from typing import Any

import numpy as np
import trimesh

from generator.articulated import atomic_write_bytes

from .validate import (
    Check,
    RepairRecord,
    Tolerances,
    read_obj_vertices,
    read_urdf,
)

log = logging.getLogger(__name__)

#: Fraction of a drawer's length kept inside the base after shortening its range.
ENGAGED_TARGET = 0.15
#: A shortened range keeps at least this fraction of the original, else unrepairable.
MIN_RANGE_KEPT = 0.25
#: Extra clearance (m) added when shrinking overlapping pieces.
SHRINK_MARGIN = 0.001
#: A piece may lose at most this fraction of its extent along the contact normal.
MAX_SHRINK = 0.5
#: Damping ceilings (N s/m for prismatic, N m s/rad for revolute) and friction floor.
MAX_DAMPING = {"prismatic": 20.0, "revolute": 5.0}
MIN_DAMPING = {"prismatic": 1.0, "revolute": 0.2}
MIN_FRICTION = 0.1
MAX_FRICTION = 2.0

REPAIR_ORDER = ("hinge_on_part", "opens_outward", "drawer_engaged", "rest_drift")


def _fmt(x: float) -> str:
    return f"{float(x):.9g}"


def _vec(v: Any) -> str:
    return " ".join(_fmt(x) for x in np.asarray(v, dtype=float).reshape(-1))


class AssetEdit:
    """Pending edits to one built asset; :meth:`commit` writes them all atomically."""

    def __init__(self, asset_dir: Path) -> None:
        self.dir = asset_dir
        self.urdf_path = asset_dir / "model.urdf"
        self.urdf = ET.parse(self.urdf_path)
        self.mjcf_path = asset_dir / "model.xml"
        self.mjcf = ET.parse(self.mjcf_path) if self.mjcf_path.is_file() else None
        self.meta_path = asset_dir / "asset.json"
        self.meta: dict[str, Any] | None = (
            json.loads(self.meta_path.read_text()) if self.meta_path.is_file() else None
        )
        self.files: dict[Path, bytes] = {}
        self.touched: set[str] = set()

    # --- element access
    def joint(self, name: str) -> ET.Element:
        el = self.urdf.getroot().find(f"joint[@name='{name}']")
        if el is None:
            raise KeyError(name)
        return el

    def link(self, name: str) -> ET.Element:
        el = self.urdf.getroot().find(f"link[@name='{name}']")
        if el is None:
            raise KeyError(name)
        return el

    def mjcf_joint(self, name: str) -> ET.Element | None:
        return None if self.mjcf is None else self.mjcf.getroot().find(f".//joint[@name='{name}']")

    def mjcf_body(self, name: str) -> ET.Element | None:
        return None if self.mjcf is None else self.mjcf.getroot().find(f".//body[@name='{name}']")

    def meta_joint(self, name: str) -> dict[str, Any] | None:
        if self.meta is None:
            return None
        return next((j for j in self.meta.get("joints", []) if j.get("name") == name), None)

    def set_file(self, path: Path, data: bytes) -> None:
        self.files[path] = data
        self.touched.add(str(path.relative_to(self.dir)))

    # --- write
    def commit(self) -> list[str]:
        for path, data in self.files.items():
            atomic_write_bytes(path, data)
        if self.mjcf is not None:
            atomic_write_bytes(self.mjcf_path, _xml_bytes(self.mjcf))
            self.touched.add("model.xml")
        atomic_write_bytes(self.urdf_path, _xml_bytes(self.urdf))
        self.touched.add("model.urdf")
        if self.meta is not None:
            atomic_write_bytes(self.meta_path, json.dumps(self.meta, indent=2).encode())
            self.touched.add("asset.json")
        return sorted(self.touched)


def _xml_bytes(tree: ET.ElementTree) -> bytes:
    return ET.tostring(tree.getroot(), encoding="utf-8", xml_declaration=True) + b"\n"


def _shift_obj_text(text: str, delta: np.ndarray) -> str:
    """OBJ text with every vertex position moved by ``delta`` (other lines unchanged)."""
    out = []
    for line in text.splitlines():
        if line.startswith("v "):
            parts = line.split()
            p = np.array([float(x) for x in parts[1:4]]) + delta
            line = "v " + _vec(p) + ("" if len(parts) <= 4 else " " + " ".join(parts[4:]))
        out.append(line)
    return "\n".join(out) + "\n"


def _write_obj(vertices: np.ndarray, original: str) -> str:
    """``original`` OBJ text with its vertex lines replaced by ``vertices`` in order."""
    it = iter(vertices)
    out = []
    for line in original.splitlines():
        if line.startswith("v "):
            line = "v " + _vec(next(it))
        out.append(line)
    return "\n".join(out) + "\n"


# --------------------------------------------------------------------------- repairs


def flip_axis(edit: AssetEdit, joint: str, reason: str) -> RepairRecord:
    el = edit.joint(joint)
    ax = el.find("axis")
    before = np.array([float(v) for v in ax.get("xyz", "1 0 0").split()])  # type: ignore[union-attr]
    after = -before
    ax.set("xyz", _vec(after))  # type: ignore[union-attr]
    mj = edit.mjcf_joint(joint)
    if mj is not None and mj.get("axis"):
        mj.set("axis", _vec(-np.array([float(v) for v in mj.get("axis", "").split()])))
    meta = edit.meta_joint(joint)
    if meta is not None:  # asset.json holds the axis in the object (base) frame
        R = read_urdf(edit.urdf_path).joints[joint].origin[:3, :3]
        meta["axis"] = (R @ after).tolist()
    return RepairRecord("flip_axis", joint, before.tolist(), after.tolist(), reason)


def shorten_range(
    edit: AssetEdit, joint: str, details: dict[str, Any], reason: str
) -> RepairRecord | str:
    lower, upper = float(details["lower"]), float(details["upper"])
    need = ENGAGED_TARGET * float(details["length"]) - float(details["overlap"])
    new_upper = upper - need
    if new_upper - lower < MIN_RANGE_KEPT * (upper - lower) or new_upper - lower < 0.01:
        return (
            f"{joint}: the range would shrink from {upper - lower:.3f} m to "
            f"{new_upper - lower:.3f} m to keep the part engaged; the part is too short for its slide"
        )
    edit.joint(joint).find("limit").set("upper", _fmt(new_upper))  # type: ignore[union-attr]
    mj = edit.mjcf_joint(joint)
    if mj is not None and mj.get("range"):
        mj.set("range", _vec([lower, new_upper]))
    meta = edit.meta_joint(joint)
    if meta is not None:
        meta["upper"] = new_upper
    return RepairRecord(
        "shorten_prismatic_range", joint, [lower, upper], [lower, new_upper], reason
    )


def add_damping(
    edit: AssetEdit,
    joint: str,
    jtype: str,
    details: dict[str, Any],
    drift: float,
    limit: float,
    reason: str,
) -> RepairRecord | str:
    d0, f0 = float(details.get("damping", 0.0)), float(details.get("friction", 0.0))
    duration = float(details.get("duration", 2.0))
    tau = abs(float(details.get("gravity_force", 0.0)))
    cap = MAX_DAMPING.get(jtype, 5.0)
    # damping that would hold the measured gravity force to half the tolerance
    need = tau * duration / (0.5 * limit) if limit > 0 else cap
    d1 = min(cap, max(2.0 * d0, MIN_DAMPING.get(jtype, 0.2), min(need, cap)))
    # PhysX joint friction resists up to about ``friction * |joint load|``; the load of a
    # resting part is about its weight, so holding the gravity force needs roughly
    # tau / (m g) (measured: 0.5 holds an 18.7 kg oven door with 17 N m, 0.05 does not)
    weight = 9.81 * max(float(details.get("mass", 0.0)), 1e-6)
    f1 = min(MAX_FRICTION, max(4.0 * f0, MIN_FRICTION, 2.0 * tau / weight))
    if d1 <= d0 + 1e-12 and f1 <= f0 + 1e-12:
        return (
            f"{joint}: drifts {drift:.4f} under a gravity force of {tau:.3f} even with damping "
            f"{d0:g} and friction {f0:g} (ceilings {cap:g}, {MAX_FRICTION:g}); the part is not "
            "balanced at rest"
        )
    dyn = edit.joint(joint).find("dynamics")
    if dyn is None:
        dyn = ET.SubElement(edit.joint(joint), "dynamics")
    dyn.set("damping", _fmt(d1))
    dyn.set("friction", _fmt(f1))
    mj = edit.mjcf_joint(joint)
    if mj is not None:
        mj.set("damping", _fmt(d1))
        mj.set("frictionloss", _fmt(f1))
    meta = edit.meta_joint(joint)
    if meta is not None:
        meta["damping"], meta["friction"] = d1, f1
    return RepairRecord(
        "add_damping",
        joint,
        {"damping": d0, "friction": f0},
        {"damping": d1, "friction": f1},
        reason,
    )


def project_hinge(
    edit: AssetEdit, joint: str, details: dict[str, Any], reason: str
) -> RepairRecord:
    """Move the hinge onto the part's AABB surface; shift the link-frame geometry back."""
    spec = read_urdf(edit.urdf_path)
    js = spec.joints[joint]
    delta = np.asarray(details["target_link"], dtype=float)  # new origin, in the old link frame
    a = js.unit_axis
    delta = delta - (delta @ a) * a  # moving along the hinge line changes nothing
    el = edit.joint(joint)
    o = el.find("origin")
    if o is None:
        o = ET.SubElement(el, "origin")
    before = js.origin[:3, 3].copy()
    after = before + js.origin[:3, :3] @ delta
    o.set("xyz", _vec(after))
    child = js.child
    link = edit.link(child)
    inertial_o = link.find("inertial/origin")
    if inertial_o is not None:
        com = np.array([float(v) for v in inertial_o.get("xyz", "0 0 0").split()])
        inertial_o.set("xyz", _vec(com - delta))
    for piece in spec.links[child].pieces:
        R = piece.origin[:3, :3]
        text = piece.path.read_text()
        edit.set_file(piece.path, _shift_obj_text(text, -(R.T @ delta)).encode())
    for vis in link.findall("visual"):
        mesh = vis.find("geometry/mesh")
        if mesh is None:
            continue
        vpath = edit.dir / mesh.get("filename", "").removeprefix("package://")
        if not vpath.is_file():
            continue
        if vpath.suffix.lower() == ".obj":
            edit.set_file(vpath, _shift_obj_text(vpath.read_text(), -delta).encode())
        else:
            scene = trimesh.load(str(vpath), force="scene", process=False)
            scene.apply_transform(trimesh.transformations.translation_matrix(-delta))
            edit.set_file(vpath, scene.export(file_type=vpath.suffix.lstrip(".").lower()))
    # the MJCF visual OBJ is a separate file beside the GLB
    vobj = edit.dir / "visual" / f"{child}.obj"
    if vobj.is_file() and vobj not in edit.files:
        edit.set_file(vobj, _shift_obj_text(vobj.read_text(), -delta).encode())
    body = edit.mjcf_body(child)
    if body is not None:
        pos = np.array([float(v) for v in body.get("pos", "0 0 0").split()])
        body.set("pos", _vec(pos + js.origin[:3, :3] @ delta))
        inert = body.find("inertial")
        if inert is not None and inert.get("pos"):
            p = np.array([float(v) for v in inert.get("pos", "").split()])
            inert.set("pos", _vec(p - delta))
    meta = edit.meta_joint(joint)
    if meta is not None and "origin" in meta:
        meta["origin"] = (
            np.asarray(meta["origin"], dtype=float) + js.origin[:3, :3] @ delta
        ).tolist()
    if edit.meta is not None:
        h = edit.meta.get("handles", {}).get(child)
        if h is not None and "position_link" in h:
            h["position_link"] = (np.asarray(h["position_link"], dtype=float) - delta).tolist()
    return RepairRecord("project_hinge_origin", joint, before.tolist(), after.tolist(), reason)


def shrink_pieces(
    edit: AssetEdit, pairs: list[dict[str, Any]], root: str, reason: str
) -> tuple[list[RepairRecord], list[str]]:
    """Shrink the movable side(s) of overlapping piece pairs along the contact normal."""
    spec = read_urdf(edit.urdf_path)
    poses = spec.link_poses()
    verts: dict[tuple[str, int], np.ndarray] = {}
    records, problems = [], []
    for pair in pairs:
        links, pieces, depth = pair["links"], pair["pieces"], float(pair["depth"])
        movable = [(ln, k) for ln, k in zip(links, pieces, strict=True) if ln != root]
        if not movable:
            problems.append(f"{links}: base pieces overlap each other")
            continue
        amount = depth / len(movable) + SHRINK_MARGIN
        n_world = np.asarray(pair["normal"], dtype=float)
        for ln, k in movable:
            piece = spec.links[ln].pieces[k]
            key = (ln, k)
            if key not in verts:
                verts[key] = read_obj_vertices(piece.path)
            v = verts[key]
            # contact normal in the piece's own frame
            R = poses[ln][:3, :3] @ piece.origin[:3, :3]
            n = R.T @ n_world
            n /= np.linalg.norm(n)
            c = v.mean(0)
            s = (v - c) @ n
            h = float(np.abs(s).max())
            if h <= 0 or amount / h > MAX_SHRINK:
                problems.append(
                    f"{ln} piece {k}: overlap {depth * 1000:.1f} mm would need more than "
                    f"{MAX_SHRINK:.0%} of its {2 * h * 1000:.1f} mm extent"
                )
                continue
            scale = (h - amount) / h
            before = [float(s.min()), float(s.max())]
            verts[key] = v - np.outer(s * (1 - scale), n)
            records.append(
                RepairRecord(
                    "shrink_piece",
                    f"{ln}#{k}",
                    {"extent_along_normal": before},
                    {
                        "extent_along_normal": [before[0] * scale, before[1] * scale],
                        "normal": n.tolist(),
                    },
                    reason,
                )
            )
    for (ln, k), v in verts.items():
        piece = spec.links[ln].pieces[k]
        edit.set_file(piece.path, _write_obj(v, piece.path.read_text()).encode())
    return records, list(dict.fromkeys(problems))


# --------------------------------------------------------------------------- planning


def plan_and_apply(
    asset_dir: str | Path, checks: list[Check], tol: Tolerances, round_: int = 1
) -> tuple[list[RepairRecord], list[str]]:
    """Repair what the failed ``checks`` allow; return (records applied, unrepairable reasons)."""
    asset_dir = Path(asset_dir)
    failed = [c for c in checks if not c.passed]
    edit = AssetEdit(asset_dir)
    spec = read_urdf(edit.urdf_path)
    root = spec.roots[0] if spec.roots else "base"
    records: list[RepairRecord] = []
    problems: list[str] = []
    done_joints: set[str] = set()
    by_name: dict[str, list[Check]] = {}
    for c in failed:
        by_name.setdefault(c.name, []).append(c)
    for name in REPAIR_ORDER:
        for c in by_name.get(name, []):
            j = c.subject
            if j in done_joints or j not in spec.joints:
                continue
            js = spec.joints[j]
            why = f"{c.key}: {c.message}"
            rec: RepairRecord | str
            if name == "hinge_on_part":
                rec = project_hinge(edit, j, c.details, why)
            elif name == "opens_outward":
                rec = flip_axis(edit, j, why)
            elif name == "drawer_engaged":
                rec = shorten_range(edit, j, c.details, why)
            else:  # rest_drift
                lim = c.tolerance["drift"] if isinstance(c.tolerance, dict) else 0.0
                rec = add_damping(edit, j, js.type, c.details, float(c.value["drift"]), lim, why)
            if isinstance(rec, str):
                problems.append(rec)
                continue
            done_joints.add(j)
            records.append(rec)
    for c in by_name.get("rest_penetration", []):
        pairs = [
            p
            for p in c.details.get("pairs", [])
            if not (
                {spec.joint_of(ln).name for ln in p["links"] if spec.joint_of(ln)} & done_joints
            )
        ]
        recs, probs = shrink_pieces(edit, pairs, root, f"{c.key}: {c.message}")
        records += recs
        problems += probs
    repairable = set(REPAIR_ORDER) | {"rest_penetration"}
    for c in failed:
        if c.name not in repairable:
            problems.append(f"{c.key}: no automatic repair ({c.message or 'failed'})")
    if records:
        files = edit.commit()
        for r in records:
            r.round = round_
            r.files = files
        log.info(
            "%s: round %d: %d repairs: %s",
            asset_dir.name,
            round_,
            len(records),
            ", ".join(f"{r.kind}({r.target})" for r in records),
        )
    return records, list(dict.fromkeys(problems))

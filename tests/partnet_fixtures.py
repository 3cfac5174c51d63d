"""Objects written in the PartNet-Mobility layout, for the importer's tests (no real data).

:func:`write_partnet` writes a list of :class:`LinkSpec` (meshes and joints in this
project's frame, metres) as a PartNet-Mobility object folder the way the dataset
stores it: ``mobility.urdf`` with a geometry-less root link ``base``, the body
``link_<n>`` fixed to it with the dataset's ``rpy = (pi/2, 0, -pi/2)``, every
movable ``link_k`` at its joint origin with ``<visual>`` origins of minus that
origin, the meshes as ``textured_objs/original-<i>.obj`` (+ ``.mtl``, some with a PNG
texture under ``images/``) in the raw y-up frame (raw ``(x, y, z)`` = ours
``(y, z, x)``, in units of ``unit`` metres), ``semantics.txt``, ``mobility_v2.json``,
``result.json`` (with ``handle`` nodes) and ``meta.json``. Options make the hard
variants the importer must undo: an object turned about +z (``yaw_deg``), no root
rotation, a joint range written negative (``flip``), a part modelled open
(``open_at``), a joint frozen as fixed in the URDF only (``fixed_in_urdf``).

:func:`links_from_object` turns a procedural object (``generator.procedural``) into
link specs (one OBJ per primitive, the handle's primitives in a ``handle`` node);
the ``*_object`` functions build the hand-made hard cases.
"""

from __future__ import annotations

import json
import math
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np
import trimesh
from PIL import Image

from generator.articulated import ArticulatedObject, Joint, Part

#: ours = RAW_TO_OURS @ raw (the PartNet convention: raw y-up, front +z).
RAW_TO_OURS = np.array([[0.0, 0.0, 1.0], [1.0, 0.0, 0.0], [0.0, 1.0, 0.0]])
ROOT_RPY = "1.570796326794897 0 -1.570796326794897"
#: Colours of the 2x2 test texture (RGB), one per quadrant.
TEXTURE_COLOURS = ((220, 30, 30), (30, 200, 40), (40, 60, 220), (230, 210, 40))


@dataclass
class MeshSpec:
    """One OBJ file: ``mesh`` in our frame (metres); ``node`` names its result.json leaf.

    Meshes of one link with the same ``group`` share one leaf node (a handle made of a
    bar and two standoffs). ``texture`` writes UVs (repeated ``repeats`` times across
    each face) and the 2x2 PNG texture; otherwise the MTL holds the flat ``color``.
    """

    mesh: trimesh.Trimesh
    node: str = "panel"
    color: tuple[int, int, int] = (200, 200, 200)
    texture: bool = False
    group: str | None = None
    repeats: float = 2.0


@dataclass
class JointSpec:
    """A joint in our frame: ``origin`` a point on the axis, positive motion opens."""

    type: str  # revolute | prismatic | continuous | fixed
    origin: np.ndarray
    axis: np.ndarray
    lower: float = 0.0
    upper: float = 0.0


@dataclass
class LinkSpec:
    """One URDF link: the body (``joint`` None) or a part on a joint to ``parent``."""

    semantic: str  # semantics.txt label: furniture_body, rotation_door, drawer, knob, ...
    kind: str  # semantics.txt / mobility_v2 joint kind: heavy, hinge, slider, static
    meshes: list[MeshSpec] = field(default_factory=list)
    joint: JointSpec | None = None
    parent: int | None = None  # index of the parent link; None: the body
    name: str = "part"  # mobility_v2 name


def _raw(points: np.ndarray, unit: float, yaw_deg: float) -> np.ndarray:
    """Our-frame points (metres) -> raw PartNet coordinates, after turning the object by yaw."""
    R = trimesh.transformations.rotation_matrix(math.radians(yaw_deg), [0, 0, 1])[:3, :3]
    return (np.asarray(points, float) @ R.T) @ RAW_TO_OURS / unit  # row-vector M^T


def _rawdir(v: np.ndarray, yaw_deg: float) -> np.ndarray:
    return _raw(np.asarray(v, float)[None], 1.0, yaw_deg)[0]


def _texture_png(path: Path) -> None:
    path.parent.mkdir(parents=True, exist_ok=True)
    img = Image.new("RGB", (16, 16))
    for k, c in enumerate(TEXTURE_COLOURS):
        x, y = (k % 2) * 8, (k // 2) * 8
        img.paste(c, (x, y, x + 8, y + 8))
    img.save(path)


def _write_obj(folder: Path, stem: str, verts: np.ndarray, spec: MeshSpec) -> None:
    """OBJ + MTL; textured meshes get one vertex per face corner with box-projected UVs."""
    faces = np.asarray(spec.mesh.faces)
    lines = [f"# test fixture\nmtllib {stem}.mtl\no {stem}"]
    if spec.texture:
        normals = spec.mesh.face_normals
        corners = faces.reshape(-1)
        v = verts[corners]
        ours = np.asarray(spec.mesh.vertices)[corners]
        drop = np.repeat(np.argmax(np.abs(normals), axis=1), 3)
        uv = np.empty((len(v), 2))
        lo, ext = ours.min(0), np.maximum(np.ptp(ours, axis=0), 1e-9)
        for i, d in enumerate(drop):
            a, b = [k for k in range(3) if k != d]
            uv[i] = (ours[i, a] - lo[a]) / ext[a], (ours[i, b] - lo[b]) / ext[b]
        uv *= spec.repeats
        lines += [f"v {x:.7f} {y:.7f} {z:.7f}" for x, y, z in v]
        lines += [f"vt {a:.6f} {b:.6f}" for a, b in uv]
        lines.append("usemtl material_0")
        lines += [
            f"f {3 * i + 1}/{3 * i + 1} {3 * i + 2}/{3 * i + 2} {3 * i + 3}/{3 * i + 3}"
            for i in range(len(faces))
        ]
    else:
        lines += [f"v {x:.7f} {y:.7f} {z:.7f}" for x, y, z in verts]
        lines.append("usemtl material_0")
        lines += [f"f {a + 1} {b + 1} {c + 1}" for a, b, c in faces]
    (folder / f"{stem}.obj").write_text("\n".join(lines) + "\n")
    kd = " ".join(f"{c / 255:.4f}" for c in spec.color)
    mtl = f"newmtl material_0\nKa 0 0 0\nKd {kd}\nKs 0.1 0.1 0.1\nd 1\n"
    if spec.texture:
        mtl += "map_Kd ../images/texture_0.png\n"
        _texture_png(folder.parent / "images" / "texture_0.png")
    (folder / f"{stem}.mtl").write_text(mtl)


def write_partnet(
    folder: str | Path,
    links: list[LinkSpec],
    *,
    model_cat: str = "StorageFurniture",
    anno_id: str = "100",
    unit: float = 0.6,
    yaw_deg: float = 0.0,
    root_rotation: bool = True,
    flip: tuple[int, ...] = (),
    open_at: dict[int, float] | None = None,
    fixed_in_urdf: tuple[int, ...] = (),
) -> Path:
    """Write ``links`` as a PartNet-Mobility object folder; return the folder.

    ``unit``: metres per raw unit. ``yaw_deg`` turns the object about +z first (its
    front then faces that way). ``root_rotation=False`` leaves out the root joint's
    rpy (raw y-up meshes in a y-up URDF). ``flip``: link indices whose joint is
    written with the axis reversed and a negative range. ``open_at``: link index ->
    joint value at which that part's meshes are written (the URDF range is shifted
    so the closed pose stays ``lower``). ``fixed_in_urdf``: link indices whose URDF
    joint is written ``fixed`` (mobility_v2.json keeps the real one, as GenSim2 did).
    """
    folder = Path(folder)
    tex = folder / "textured_objs"
    tex.mkdir(parents=True, exist_ok=True)
    open_at = open_at or {}
    bodies = [i for i, lk in enumerate(links) if lk.joint is None]
    assert len(bodies) == 1, "exactly one body link (joint None)"
    body = bodies[0]
    # URDF names: movable links first (link_0..), the body last, as in the dataset
    order = [i for i in range(len(links)) if i != body] + [body]
    lname = {i: f"link_{k}" for k, i in enumerate(order)}
    vid = {i: k for k, i in enumerate(order)}

    origin_raw: dict[int, np.ndarray] = {body: np.zeros(3)}
    for i, lk in enumerate(links):
        if lk.joint is not None:
            origin_raw[i] = _raw(lk.joint.origin[None], unit, yaw_deg)[0]

    node_id = [2]
    result_children: list[dict] = []
    v2: list[dict] = []
    urdf = ['<?xml version="1.0" ?>', '<robot name="partnet_fixture">', '\t<link name="base"/>']
    obj_index = [0]
    for i in order:
        lk = links[i]
        j = lk.joint
        q_open = open_at.get(i, 0.0)
        leaves: dict[str, dict] = {}
        visuals = []
        for ms in lk.meshes:
            mesh = ms.mesh
            if j is not None and q_open:  # the part is modelled open at q_open
                mesh = mesh.copy()
                mesh.apply_transform(Joint(j.type, j.origin, j.axis).transform(q_open))
            stem = f"original-{obj_index[0]}"
            obj_index[0] += 1
            _write_obj(
                tex,
                stem,
                _raw(mesh.vertices, unit, yaw_deg),
                MeshSpec(**{**ms.__dict__, "mesh": mesh}),
            )
            key = ms.group or stem
            if key not in leaves:
                leaves[key] = {"id": node_id[0], "name": ms.node, "text": ms.node, "objs": []}
                node_id[0] += 1
            leaves[key]["objs"].append(stem)
            visuals.append((f"{ms.node}-{leaves[key]['id']}", stem))
        o = origin_raw[i]
        urdf.append(f'\t<link name="{lname[i]}">')
        for vname, stem in visuals:
            for tag in ("visual", "collision"):
                nm = f' name="{vname}"' if tag == "visual" else ""
                urdf += [
                    f"\t\t<{tag}{nm}>",
                    f'\t\t\t<origin xyz="{-o[0]} {-o[1]} {-o[2]}"/>',
                    f'\t\t\t<geometry><mesh filename="textured_objs/{stem}.obj"/></geometry>',
                    f"\t\t</{tag}>",
                ]
        urdf.append("\t</link>")
        part_nodes = list(leaves.values())
        node = {"id": node_id[0], "name": lk.name, "text": lk.name, "children": part_nodes}
        node_id[0] += 1
        result_children.append(node)
        entry = {
            "id": vid[i],
            "parent": -1 if j is None else vid[body if lk.parent is None else lk.parent],
            "joint": lk.kind,
            "name": lk.name,
            "parts": [{"id": n["id"], "name": n["name"], "children": []} for n in part_nodes],
            "jointData": {},
        }
        if j is None:
            urdf += [
                f'\t<joint name="joint_{vid[i]}" type="fixed">',
                f'\t\t<origin rpy="{ROOT_RPY if root_rotation else "0 0 0"}" xyz="0 0 0"/>',
                f'\t\t<child link="{lname[i]}"/>',
                '\t\t<parent link="base"/>',
                "\t</joint>",
            ]
        else:
            parent = body if lk.parent is None else lk.parent
            axis = _rawdir(j.axis, yaw_deg)
            lo, hi = j.lower - q_open, j.upper - q_open
            if j.type == "prismatic":
                lo, hi = lo / unit, hi / unit
            if i in flip:
                axis, lo, hi = -axis, -hi, -lo
            rel = o - origin_raw[parent]
            jtype = "fixed" if i in fixed_in_urdf else j.type
            urdf += [
                f'\t<joint name="joint_{vid[i]}" type="{jtype}">',
                f'\t\t<origin xyz="{rel[0]} {rel[1]} {rel[2]}"/>',
                f'\t\t<axis xyz="{axis[0]} {axis[1]} {axis[2]}"/>',
                f'\t\t<child link="{lname[i]}"/>',
                f'\t\t<parent link="{lname[parent]}"/>',
            ]
            if j.type in ("revolute", "prismatic"):
                urdf.append(f'\t\t<limit lower="{lo}" upper="{hi}"/>')
            urdf.append("\t</joint>")
            deg = j.type in ("revolute", "continuous")
            entry["jointData"] = {
                "axis": {"origin": o.tolist(), "direction": axis.tolist()},
                "limit": {
                    "a": math.degrees(lo) if deg else lo,
                    "b": math.degrees(hi) if deg else hi,
                    "noLimit": j.type == "continuous",
                },
            }
        v2.append(entry)
    urdf.append("</robot>")
    (folder / "mobility.urdf").write_text("\n".join(urdf) + "\n")
    (folder / "semantics.txt").write_text(
        "".join(f"{lname[i]} {links[i].kind} {links[i].semantic}\n" for i in order)
    )
    (folder / "mobility_v2.json").write_text(json.dumps(sorted(v2, key=lambda e: e["id"])))
    root = {"id": 0, "name": model_cat.lower(), "text": model_cat, "children": result_children}
    (folder / "result.json").write_text(json.dumps([root]))
    (folder / "meta.json").write_text(
        json.dumps({"model_cat": model_cat, "anno_id": anno_id, "version": "2"})
    )
    return folder


# --------------------------------------------------------------------------- procedural


def part_color(part: Part) -> tuple[int, int, int]:
    vis = part.mesh.visual
    if vis.kind == "texture":
        vis = vis.to_color()
    c = np.asarray(vis.vertex_colors, float).mean(axis=0)
    return tuple(int(x) for x in c[:3].round())


def handle_primitives(part: Part) -> list[int]:
    """Indices of the primitives forming the part's modelled handle (bar + posts, knob + stem).

    The primitive(s) containing the handle point, then the small primitives touching them.
    """
    if part.handle is None or part.handle.kind not in ("bar", "knob"):
        return []
    boxes = [p.to_mesh().bounds for p in part.primitives]
    vols = [float(np.prod(p.to_mesh().extents)) for p in part.primitives]
    h = part.handle.position
    seed = [i for i, b in enumerate(boxes) if (b[0] - 1e-6 <= h).all() and (h <= b[1] + 1e-6).all()]
    if not seed:
        return []
    seed = [min(seed, key=lambda i: vols[i])]
    vmax = 2.0 * max(vols[i] for i in seed)
    out = set(seed)
    for _ in range(3):
        for i, b in enumerate(boxes):
            if i in out or vols[i] > vmax:
                continue
            if any(
                (b[0] <= boxes[s][1] + 1e-4).all() and (boxes[s][0] <= b[1] + 1e-4).all()
                for s in out
            ):
                out.add(i)
    return sorted(out)


SEMANTIC = {"door": "rotation_door", "drawer": "drawer", "lid": "lid"}


def links_from_object(obj: ArticulatedObject, textured: bool = True) -> list[LinkSpec]:
    """Link specs of a procedural object: one OBJ per primitive, handles in ``handle`` nodes.

    The first primitive of the base and of every movable part is textured when
    ``textured``; the others carry the part's mean colour.
    """
    links: list[LinkSpec] = []
    for part in obj.parts:
        colour = part_color(part)
        hp = set(handle_primitives(part))
        meshes = []
        for k, prim in enumerate(part.primitives):
            meshes.append(
                MeshSpec(
                    prim.to_mesh(),
                    node="handle"
                    if k in hp
                    else ("frame" if part.is_base else f"{part.semantic}_front"),
                    color=colour,
                    texture=textured and k == 0,
                    group="handle" if k in hp else None,
                )
            )
        if part.joint is None:
            links.append(LinkSpec("furniture_body", "heavy", meshes, None, name="frame"))
            continue
        j = part.joint
        links.append(
            LinkSpec(
                SEMANTIC.get(part.semantic, part.semantic),
                "hinge" if j.type == "revolute" else "slider",
                meshes,
                JointSpec(j.type, j.origin.copy(), j.axis.copy(), j.lower, j.upper),
                name=part.semantic,
            )
        )
    return links


# --------------------------------------------------------------------------- hard cases


def quad(corners: list[list[float]]) -> trimesh.Trimesh:
    """One single-sided quad (two triangles) through four corners in order."""
    return trimesh.Trimesh(np.asarray(corners, float), [[0, 1, 2], [0, 2, 3]], process=False)


def box(lo: list[float], hi: list[float]) -> trimesh.Trimesh:
    lo_, hi_ = np.asarray(lo, float), np.asarray(hi, float)
    return trimesh.creation.box(
        hi_ - lo_, trimesh.transformations.translation_matrix((lo_ + hi_) / 2)
    )


def _drawer_boxes(
    y0: float, y1: float, z0: float, z1: float, x_front: float, depth: float
) -> list[trimesh.Trimesh]:
    t = 0.012
    return [
        box([x_front - t, y0, z0], [x_front, y1, z1]),  # front
        box([x_front - depth, y0, z0], [x_front - t, y1, z0 + t]),  # bottom
        box([x_front - depth, y0, z0 + t], [x_front - t, y0 + t, z1 - 0.03]),  # left
        box([x_front - depth, y1 - t, z0 + t], [x_front - t, y1, z1 - 0.03]),  # right
        box([x_front - depth, y0 + t, z0 + t], [x_front - depth + t, y1 - t, z1 - 0.03]),  # back
    ]


def open_shell_cabinet() -> list[LinkSpec]:
    """(a) A body of single-sided quads (no thickness) with an internal shelf and
    divider, and a drawer in a slot exactly 2 mm wider than the drawer.

    Body: x in [-0.25, 0.25], y in [-0.3, 0.3], z in [0, 0.8], open at the front (+x);
    slot z in [0.05, 0.35], 0.600 wide; drawer 0.598 wide, front flush at x = 0.25,
    slides +x over 0.35 m.
    """
    xb, xf, w, h = -0.25, 0.25, 0.3, 0.8
    shell = [
        quad([[xb, -w, 0], [xb, w, 0], [xb, w, h], [xb, -w, h]]),  # back
        quad([[xb, -w, 0], [xf, -w, 0], [xf, -w, h], [xb, -w, h]]),  # left
        quad([[xb, w, 0], [xb, w, h], [xf, w, h], [xf, w, 0]]),  # right
        quad([[xb, -w, h], [xf, -w, h], [xf, w, h], [xb, w, h]]),  # top
        quad([[xb, -w, 0], [xb, w, 0], [xf, w, 0], [xf, -w, 0]]),  # bottom
    ]
    internal = [
        quad([[xb, -w, 0.4], [xf, -w, 0.4], [xf, w, 0.4], [xb, w, 0.4]]),  # shelf
        quad([[xb, -w, 0.4], [xf, -w, 0.4], [xf, -w, 0.4], [xb, -w, 0.4]]),  # degenerate
        quad([[xb, 0, 0.4], [xf, 0, 0.4], [xf, 0, h], [xb, 0, h]]),  # divider
    ]
    body = [MeshSpec(m, node="frame", color=(150, 110, 70)) for m in shell]
    body += [MeshSpec(m, node="shelf", color=(150, 110, 70)) for m in internal]
    half = 0.299  # 2 mm narrower than the 0.600 slot
    drawer = [
        MeshSpec(m, node="drawer_box", color=(190, 150, 100), texture=(k == 0))
        for k, m in enumerate(_drawer_boxes(-half, half, 0.05, 0.35, xf, 0.45))
    ]
    return [
        LinkSpec("furniture_body", "heavy", body, name="frame"),
        LinkSpec(
            "drawer",
            "slider",
            drawer,
            JointSpec("prismatic", np.array([0.0, 0.0, 0.2]), np.array([1.0, 0.0, 0.0]), 0.0, 0.35),
            name="drawer",
        ),
    ]


def cabinet_body(
    depth: float = 0.5, width: float = 0.6, height: float = 0.8, t: float = 0.02
) -> list[MeshSpec]:
    xb, xf, w = -depth / 2, depth / 2, width / 2
    boxes = [
        box([xb, -w, 0], [xf, w, t]),
        box([xb, -w, height - t], [xf, w, height]),
        box([xb, -w, t], [xf, -w + t, height - t]),
        box([xb, w - t, t], [xf, w, height - t]),
        box([xb, -w + t, t], [xb + t, w - t, height - t]),
    ]
    return [
        MeshSpec(b, node="frame", color=(120, 120, 125), texture=(k == 0))
        for k, b in enumerate(boxes)
    ]


#: The bar handle of :func:`bar_handle_door`: centre, radius, length (our frame, metres).
BAR_CENTRE = np.array([0.25 + 0.018 + 0.035, 0.22, 0.45])
BAR_RADIUS = 0.008
BAR_LENGTH = 0.20


def bar_handle_door(kind: str = "bar") -> list[LinkSpec]:
    """(b) A cabinet with one side-hinged door (hinge at y = -0.29, opening +x) carrying a
    modelled bar handle: two box standoffs and a cylinder bar along z, one ``handle``
    node; ``kind="knob"`` gives a round knob (stem + disc) instead.
    """
    xf, t = 0.25, 0.018
    door = [
        MeshSpec(
            box([xf, -0.29, 0.02], [xf + t, 0.29, 0.78]), node="door_frame", color=(200, 200, 205)
        )
    ]
    face = xf + t
    c = BAR_CENTRE
    if kind == "bar":
        bar = trimesh.creation.cylinder(BAR_RADIUS, BAR_LENGTH, sections=24)
        bar.apply_translation(c)
        parts = [bar]
        for dz in (-0.08, 0.08):
            parts.append(
                box(
                    [face, c[1] - 0.006, c[2] + dz - 0.006], [c[0], c[1] + 0.006, c[2] + dz + 0.006]
                )
            )
    else:
        stem = trimesh.creation.cylinder(0.005, 0.02, sections=16)
        stem.apply_transform(trimesh.transformations.rotation_matrix(math.pi / 2, [0, 1, 0]))
        stem.apply_translation([face + 0.01, c[1], c[2]])
        disc = trimesh.creation.cylinder(0.015, 0.015, sections=24)
        disc.apply_transform(trimesh.transformations.rotation_matrix(math.pi / 2, [0, 1, 0]))
        disc.apply_translation([face + 0.02 + 0.0075, c[1], c[2]])
        parts = [stem, disc]
    door += [MeshSpec(m, node="handle", color=(40, 40, 40), group="handle") for m in parts]
    return [
        LinkSpec("furniture_body", "heavy", cabinet_body(), name="frame"),
        LinkSpec(
            "rotation_door",
            "hinge",
            door,
            JointSpec("revolute", np.array([xf, -0.29, 0.0]), np.array([0.0, 0.0, -1.0]), 0.0, 1.9),
            name="door",
        ),
    ]


def many_pieces_drawer(n_side: int = 6) -> list[LinkSpec]:
    """(c) A drawer whose front carries ``n_side`` x ``n_side`` separate studs, written as
    three OBJ files of disconnected boxes each (so the part is 5 + n_side**2 pieces)."""
    xf = 0.25
    drawer = _drawer_boxes(-0.28, 0.28, 0.05, 0.35, xf, 0.4)
    studs = []
    for i in range(n_side):
        for k in range(n_side):
            y = -0.2 + 0.4 * i / (n_side - 1)
            z = 0.1 + 0.2 * k / (n_side - 1)
            studs.append(box([xf, y - 0.01, z - 0.01], [xf + 0.008, y + 0.01, z + 0.01]))
    files = [trimesh.util.concatenate(studs[j::3]) for j in range(3)]
    meshes = [MeshSpec(m, node="drawer_front", color=(90, 60, 40)) for m in drawer + files]
    return [
        LinkSpec("furniture_body", "heavy", cabinet_body(height=0.4), name="frame"),
        LinkSpec(
            "drawer",
            "slider",
            meshes,
            JointSpec("prismatic", np.array([0.0, 0.0, 0.2]), np.array([1.0, 0.0, 0.0]), 0.0, 0.3),
            name="drawer",
        ),
    ]


#: Knob centres of :func:`oven_with_knobs` (our frame, metres).
KNOB_CENTRES = [np.array([0.3 + 0.012, y, 0.82]) for y in (-0.2, -0.07, 0.07, 0.2)]


def oven_with_knobs() -> list[LinkSpec]:
    """(d) An oven: body, a bottom-hinged door with a bar handle, four knobs on their
    own continuous joints (axis +x) and a push button on a 2 mm prismatic joint."""
    body = cabinet_body(depth=0.6, width=0.6, height=0.9)
    body.append(
        MeshSpec(box([0.28, -0.3, 0.76], [0.3, 0.3, 0.9]), node="control_panel", color=(30, 30, 30))
    )
    door = [
        MeshSpec(
            box([0.3, -0.28, 0.05], [0.32, 0.28, 0.74]), node="door_frame", color=(60, 60, 60)
        ),
        MeshSpec(box([0.305, -0.2, 0.3], [0.325, 0.2, 0.6]), node="glass", color=(20, 20, 30)),
    ]
    bar = trimesh.creation.cylinder(0.008, 0.4, sections=16)
    bar.apply_transform(trimesh.transformations.rotation_matrix(math.pi / 2, [1, 0, 0]))
    bar.apply_translation([0.36, 0.0, 0.68])
    door.append(MeshSpec(bar, node="handle", color=(180, 180, 180), group="handle"))
    for y in (-0.15, 0.15):
        door.append(
            MeshSpec(
                box([0.32, y - 0.006, 0.674], [0.36, y + 0.006, 0.686]),
                node="handle",
                color=(180, 180, 180),
                group="handle",
            )
        )
    links = [
        LinkSpec("oven_body", "heavy", body, name="frame"),
        LinkSpec(
            "door",
            "hinge",
            door,
            JointSpec(
                "revolute", np.array([0.31, 0.0, 0.05]), np.array([0.0, 1.0, 0.0]), 0.0, math.pi / 2
            ),
            name="door",
        ),
    ]
    for c in KNOB_CENTRES:
        knob = trimesh.creation.cylinder(0.02, 0.024, sections=20)
        knob.apply_transform(trimesh.transformations.rotation_matrix(math.pi / 2, [0, 1, 0]))
        knob.apply_translation(c)
        links.append(
            LinkSpec(
                "knob",
                "hinge",
                [MeshSpec(knob, node="knob", color=(200, 200, 200))],
                JointSpec("continuous", c.copy(), np.array([1.0, 0.0, 0.0])),
                name="knob",
            )
        )
    links.append(
        LinkSpec(
            "button",
            "slider",
            [MeshSpec(box([0.3, 0.24, 0.8], [0.31, 0.27, 0.83]), node="button", color=(250, 0, 0))],
            JointSpec(
                "prismatic", np.array([0.3, 0.255, 0.815]), np.array([-1.0, 0.0, 0.0]), 0.0, 0.002
            ),
            name="button",
        )
    )
    return links

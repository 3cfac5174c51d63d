"""The object model every package shares: an articulated object as parts and joints.

Following the PAct paper, an object is a set of parts P_i = (G_i, A_i): G_i is the
part's textured triangle mesh, A_i its articulation (joint type, semantic label,
pivot, unit axis, [lower, upper] with lower = closed, parent). The tree is depth 1:
exactly one part is the root ``base`` and every movable part hangs off it.

Frame convention (used everywhere in this project)
--------------------------------------------------
Right-handed, +z up, the object's front faces +x, origin at the centre of the
base's footprint on the floor. Units are metres when ``ArticulatedObject.scale``
is 1.0. Generators work in the normalized cube [-0.5, 0.5]^3 of the same axes and
leave ``scale`` as None (metric size unknown); the asset pipeline applies a metric
scale and moves the origin onto the floor.

On disk an object is a *bundle* (:mod:`generator.bundle`): ``object.json`` beside
``parts/<name>.glb``.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass, field
from typing import Any

import numpy as np
import trimesh

SCHEMA = "pact.object"
SCHEMA_VERSION = 1
JOINT_TYPES = ("fixed", "prismatic", "revolute")
PRIMITIVE_KINDS = ("box", "cylinder")
BASE = "base"


class ObjectModelError(ValueError):
    """An articulated object or bundle is invalid; the message names the file and field."""


# --------------------------------------------------------------------------- geometry


@dataclass
class Primitive:
    """A convex solid the part is made of, known exactly (procedural objects).

    ``kind`` is "box" (``size`` = full extents x, y, z) or "cylinder" (``size`` =
    [radius, height], axis along the primitive's local z). ``transform`` (4x4) places
    the primitive's centre and orientation in the object frame.
    """

    kind: str
    size: np.ndarray
    transform: np.ndarray = field(default_factory=lambda: np.eye(4))

    def __post_init__(self) -> None:
        self.size = np.asarray(self.size, dtype=float)
        self.transform = np.asarray(self.transform, dtype=float)

    def to_mesh(self, sections: int = 16) -> trimesh.Trimesh:
        """The primitive as a closed convex triangle mesh in the object frame."""
        if self.kind == "box":
            return trimesh.creation.box(extents=self.size, transform=self.transform)
        return trimesh.creation.cylinder(
            radius=float(self.size[0]),
            height=float(self.size[1]),
            sections=sections,
            transform=self.transform,
        )

    def to_json(self) -> dict[str, Any]:
        return {
            "kind": self.kind,
            "size": self.size.tolist(),
            "transform": self.transform.tolist(),
        }

    @classmethod
    def from_json(cls, d: dict[str, Any]) -> Primitive:
        return cls(kind=d["kind"], size=d["size"], transform=d.get("transform", np.eye(4)))


@dataclass
class Handle:
    """Where a robot grasps a movable part, in the object frame.

    ``position`` is the grasp point; ``axis`` the unit direction of the bar (the
    fingers close across it); ``kind`` is "bar", "knob", "recessed" or "none" (no
    modelled handle: the point is then the centre of the front face near the edge
    opposite the hinge).
    """

    position: np.ndarray
    axis: np.ndarray = field(default_factory=lambda: np.array([0.0, 0.0, 1.0]))
    kind: str = "bar"

    def __post_init__(self) -> None:
        self.position = np.asarray(self.position, dtype=float)
        self.axis = np.asarray(self.axis, dtype=float)

    def to_json(self) -> dict[str, Any]:
        return {"position": self.position.tolist(), "axis": self.axis.tolist(), "kind": self.kind}

    @classmethod
    def from_json(cls, d: dict[str, Any]) -> Handle:
        return cls(position=d["position"], axis=d.get("axis", [0, 0, 1]), kind=d.get("kind", "bar"))


# --------------------------------------------------------------------------- articulation


@dataclass
class Joint:
    """Joint of a part to its parent, in the object frame.

    ``origin`` is the pivot (a point on the hinge line for revolute joints),
    ``axis`` a unit vector; a positive joint value moves the part outward (opens it).
    ``lower`` is the closed configuration; units are metres (prismatic) or radians
    (revolute). A fixed joint has lower = upper = 0.
    """

    type: str
    origin: np.ndarray = field(default_factory=lambda: np.zeros(3))
    axis: np.ndarray = field(default_factory=lambda: np.array([1.0, 0.0, 0.0]))
    lower: float = 0.0
    upper: float = 0.0
    parent: str = BASE

    def __post_init__(self) -> None:
        self.origin = np.asarray(self.origin, dtype=float)
        self.axis = np.asarray(self.axis, dtype=float)
        self.lower = float(self.lower)
        self.upper = float(self.upper)

    @property
    def movable(self) -> bool:
        return self.type != "fixed"

    @property
    def range(self) -> float:
        return self.upper - self.lower

    def to_json(self) -> dict[str, Any]:
        return {
            "type": self.type,
            "origin": self.origin.tolist(),
            "axis": self.axis.tolist(),
            "lower": self.lower,
            "upper": self.upper,
            "parent": self.parent,
        }

    @classmethod
    def from_json(cls, d: dict[str, Any]) -> Joint:
        return cls(
            type=d["type"],
            origin=d.get("origin", [0, 0, 0]),
            axis=d.get("axis", [1, 0, 0]),
            lower=d.get("lower", 0.0),
            upper=d.get("upper", 0.0),
            parent=d.get("parent", BASE),
        )

    def transform(self, q: float) -> np.ndarray:
        """4x4 rigid motion of the part (object frame) at joint value ``q``."""
        T = np.eye(4)
        if self.type == "prismatic":
            T[:3, 3] = q * self.axis
        elif self.type == "revolute":
            R = trimesh.transformations.rotation_matrix(q, self.axis, point=self.origin)
            T = R
        return T


@dataclass
class Part:
    """One rigid part: geometry G_i and articulation A_i (``joint`` is None for the base)."""

    name: str
    semantic: str
    mesh: trimesh.Trimesh
    joint: Joint | None = None
    primitives: list[Primitive] = field(default_factory=list)
    handle: Handle | None = None
    material: str = "wood"

    def __post_init__(self) -> None:
        # glTF stores float32 positions; keep the model float32-representable so
        # that a saved bundle loads back bit-identical.
        if self.mesh.vertices.dtype != np.float64 or not np.array_equal(
            self.mesh.vertices, self.mesh.vertices.astype(np.float32)
        ):
            self.mesh.vertices = np.asarray(self.mesh.vertices, dtype=np.float32).astype(np.float64)
        uv = getattr(self.mesh.visual, "uv", None)
        if uv is not None:
            self.mesh.visual.uv = np.asarray(uv, dtype=np.float32).astype(np.float64)

    @property
    def is_base(self) -> bool:
        return self.joint is None

    def posed_mesh(self, q: float) -> trimesh.Trimesh:
        """The part's mesh moved to joint value ``q`` (object frame)."""
        m = self.mesh.copy()
        if self.joint is not None:
            m.apply_transform(self.joint.transform(q))
        return m


@dataclass
class ArticulatedObject:
    """A depth-1 articulated object: one ``base`` part and movable parts hanging off it.

    ``scale``: metres per model unit (1.0 for metric objects, None when the metric
    size is unknown, as for normalized generator output). ``provenance``: free-form
    record of where the object came from (generator, seed, source image, ...).
    """

    parts: list[Part]
    category: str = "unknown"
    scale: float | None = 1.0
    provenance: dict[str, Any] = field(default_factory=dict)

    # ---- access
    def part(self, name: str) -> Part:
        for p in self.parts:
            if p.name == name:
                return p
        raise KeyError(f"no part named {name!r}; parts: {[p.name for p in self.parts]}")

    @property
    def base(self) -> Part:
        return next(p for p in self.parts if p.is_base)

    @property
    def movable_parts(self) -> list[Part]:
        return [p for p in self.parts if p.joint is not None and p.joint.movable]

    def posed_meshes(self, qpos: dict[str, float] | None = None) -> dict[str, trimesh.Trimesh]:
        """Every part's mesh at the joint values ``qpos`` (missing parts at ``lower``)."""
        qpos = qpos or {}
        out = {}
        for p in self.parts:
            q = qpos.get(p.name, p.joint.lower if p.joint else 0.0)
            out[p.name] = p.posed_mesh(q)
        return out

    def bounds(self) -> np.ndarray:
        """(2, 3) axis-aligned bounds of all parts at rest."""
        b = np.array([p.mesh.bounds for p in self.parts])
        return np.stack([b[:, 0].min(0), b[:, 1].max(0)])

    # ---- validation
    def validate(self, source: str = "<object>") -> None:
        """Raise ObjectModelError naming ``source`` and the field when the model is invalid."""
        err = lambda field_, msg: ObjectModelError(f"{source}: {field_}: {msg}")  # noqa: E731
        if not self.parts:
            raise err("parts", "the object has no parts")
        names = [p.name for p in self.parts]
        dup = sorted({n for n in names if names.count(n) > 1})
        if dup:
            raise err("parts", f"part names must be unique; repeated: {dup}")
        bases = [p.name for p in self.parts if p.is_base]
        if len(bases) != 1:
            raise err("parts", f"exactly one base part (joint null) is required, found {bases}")
        if bases[0] != BASE:
            raise err(f"parts[{bases[0]}].name", f"the root part must be named {BASE!r}")
        if self.scale is not None and not (math.isfinite(self.scale) and self.scale > 0):
            raise err("scale", f"must be a positive finite number or null, got {self.scale}")
        for i, p in enumerate(self.parts):
            where = f"parts[{i}] ({p.name})"
            if not p.name or "/" in p.name or p.name.strip() != p.name:
                raise err(f"{where}.name", "must be a non-empty name without '/' or padding")
            if len(p.mesh.vertices) == 0 or len(p.mesh.faces) == 0:
                raise err(f"{where}.mesh", "the part mesh is empty")
            if not np.isfinite(p.mesh.vertices).all():
                raise err(f"{where}.mesh", "vertex positions contain NaN or inf")
            for k, prim in enumerate(p.primitives):
                if prim.kind not in PRIMITIVE_KINDS:
                    raise err(f"{where}.primitives[{k}].kind", f"must be one of {PRIMITIVE_KINDS}")
            if p.handle is not None and (
                p.handle.position.shape != (3,) or not np.isfinite(p.handle.position).all()
            ):
                raise err(f"{where}.handle.position", "must be 3 finite numbers")
            j = p.joint
            if j is None:
                continue
            if j.type not in JOINT_TYPES:
                raise err(f"{where}.joint.type", f"must be one of {JOINT_TYPES}, got {j.type!r}")
            if j.parent != BASE:
                if j.parent not in names:
                    raise err(f"{where}.joint.parent", f"parent {j.parent!r} does not exist")
                raise err(f"{where}.joint.parent", f"the tree is depth 1: parent must be {BASE!r}")
            if j.origin.shape != (3,) or not np.isfinite(j.origin).all():
                raise err(
                    f"{where}.joint.origin", f"must be 3 finite numbers, got {j.origin.tolist()}"
                )
            if j.axis.shape != (3,) or not np.isfinite(j.axis).all():
                raise err(f"{where}.joint.axis", f"must be 3 finite numbers, got {j.axis.tolist()}")
            n = float(np.linalg.norm(j.axis))
            if abs(n - 1.0) > 1e-6:
                raise err(f"{where}.joint.axis", f"must be a unit vector, has norm {n:.6g}")
            if not (math.isfinite(j.lower) and math.isfinite(j.upper)):
                raise err(f"{where}.joint.lower/upper", "limits must be finite")
            if j.movable and not j.lower < j.upper:
                raise err(
                    f"{where}.joint.lower/upper",
                    f"need lower < upper (lower = closed), got [{j.lower}, {j.upper}]",
                )

    # ---- (de)serialization
    def to_json(self) -> dict[str, Any]:
        return {
            "schema": SCHEMA,
            "version": SCHEMA_VERSION,
            "category": self.category,
            "scale": self.scale,
            "provenance": self.provenance,
            "parts": [
                {
                    "name": p.name,
                    "semantic": p.semantic,
                    "mesh": f"parts/{p.name}.glb",
                    "material": p.material,
                    "joint": None if p.joint is None else p.joint.to_json(),
                    "handle": None if p.handle is None else p.handle.to_json(),
                    "primitives": [q.to_json() for q in p.primitives],
                }
                for p in self.parts
            ],
        }


def unit(v: Sequence[float]) -> np.ndarray:
    v = np.asarray(v, dtype=float)
    return v / np.linalg.norm(v)

"""The one model of a built simulation asset: links, joints, handles, physics, files.

Build (:mod:`asset_pipeline.assets.build`) fills a :class:`BuiltAsset` from an
:class:`~generator.articulated.ArticulatedObject` (:func:`asset_pipeline.assets.rig.build_rig`
is the one place where the object model's joints become the built asset's);
repair (:mod:`asset_pipeline.validate.repair`) edits it; ``model.urdf``,
``model.xml`` and ``asset.json`` are written from it and read back into it by
:mod:`asset_pipeline.asset_io`, and nothing else reads or writes them.

Frames (docs/architecture.md): the root link's frame is the object frame. A
joint's ``origin`` places the child link frame in the parent link frame at joint
value 0; its ``axis`` is a unit vector in the child link frame (the URDF
convention). Geometry elements (:class:`Visual`, :class:`CollisionPiece`) carry their
own ``origin`` in their link frame; the inertial's centre of mass is in the link
frame. Units: metres, radians, kilograms, seconds.
"""

from __future__ import annotations

import math
from collections.abc import Mapping
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np
import trimesh

MOVABLE_JOINT_TYPES = ("prismatic", "revolute", "continuous")
#: What a handle can be (``none``: no modelled handle, a point on the front face).
HANDLE_KINDS = ("bar", "knob", "recessed", "none")
#: How a movable part moves, as the tasks report it: ``drawer`` (slides), ``side_door``
#: (vertical hinge), ``bottom_door`` (horizontal hinge below the handle: an oven or
#: dishwasher door), ``lid`` (horizontal hinge level with the handle: a top lid hinged at
#: its back), ``top_flap`` (horizontal hinge above the handle).
PART_KINDS = ("drawer", "side_door", "bottom_door", "lid", "top_flap")


@dataclass
class Inertial:
    """Mass (kg), centre of mass (3,) in the link frame, inertia (3, 3) about it (kg m^2)."""

    mass: float
    com: np.ndarray
    inertia: np.ndarray

    def __post_init__(self) -> None:
        self.mass = float(self.mass)
        self.com = np.asarray(self.com, dtype=float).reshape(3)
        self.inertia = np.asarray(self.inertia, dtype=float).reshape(3, 3)


@dataclass
class Visual:
    """A visual mesh file (relative to the asset folder) placed by ``origin`` (4, 4) in the link.

    ``mesh`` holds the geometry when it is to be written (build); it is None for an
    asset read from disk. ``obj_filename`` is the same geometry as an OBJ for MJCF (with
    its texture coordinates when textured); ``texture`` the base-colour image (PNG,
    relative to the asset folder) that the MJCF's material maps onto it, None when the
    visual has none.
    """

    filename: str
    origin: np.ndarray = field(default_factory=lambda: np.eye(4))
    name: str = ""
    mesh: trimesh.Trimesh | None = None
    texture: str | None = None

    @property
    def obj_filename(self) -> str:
        return str(Path(self.filename).with_suffix(".obj").as_posix())


@dataclass
class CollisionPiece:
    """One convex collision piece: an OBJ file (relative to the asset folder) and its pose.

    ``origin`` (4, 4) places the file's vertices in the link frame. ``mesh`` holds the
    piece when it is to be written (build, repair), else None (read lazily with
    :func:`asset_pipeline.asset_io.piece_vertices`).
    """

    filename: str
    origin: np.ndarray = field(default_factory=lambda: np.eye(4))
    name: str = ""
    mesh: trimesh.Trimesh | None = None


@dataclass
class Link:
    """One rigid part of the asset. ``rgba`` (4,) in [0, 1] is its mean colour (MJCF)."""

    name: str
    semantic: str = "part"
    material: str = "wood"
    inertial: Inertial | None = None
    visuals: list[Visual] = field(default_factory=list)
    collisions: list[CollisionPiece] = field(default_factory=list)
    rgba: np.ndarray = field(default_factory=lambda: np.array([0.7, 0.7, 0.7, 1.0]))


@dataclass(frozen=True)
class JointPhysics:
    """Damping, Coulomb friction, effort and velocity limits of a joint (SI units:
    N s/m and N for prismatic joints, N m s/rad and N m for revolute ones)."""

    damping: float = 0.0
    friction: float = 0.0
    effort: float = 100.0
    velocity: float = 1.0


@dataclass
class Joint:
    """A joint of ``child`` to ``parent``; see the module docstring for its frames.

    ``lower`` is the closed configuration; positive motion opens the part.
    """

    name: str
    type: str
    parent: str
    child: str
    origin: np.ndarray = field(default_factory=lambda: np.eye(4))
    axis: np.ndarray = field(default_factory=lambda: np.array([1.0, 0.0, 0.0]))
    lower: float = 0.0
    upper: float = 0.0
    physics: JointPhysics = field(default_factory=JointPhysics)

    def __post_init__(self) -> None:
        self.origin = np.asarray(self.origin, dtype=float).reshape(4, 4)
        self.axis = np.asarray(self.axis, dtype=float).reshape(3)
        self.lower = float(self.lower)
        self.upper = float(self.upper)

    @property
    def movable(self) -> bool:
        return self.type in MOVABLE_JOINT_TYPES

    @property
    def unit_axis(self) -> np.ndarray:
        """The axis scaled to norm 1 (unchanged when its norm is 0 or not finite)."""
        n = float(np.linalg.norm(self.axis))
        return self.axis / n if n > 0 and math.isfinite(n) else self.axis

    def motion(self, q: float) -> np.ndarray:
        """(4, 4) motion of the child in the joint frame at joint value ``q``."""
        if self.type == "prismatic":
            T = np.eye(4)
            T[:3, 3] = q * self.unit_axis
            return T
        if self.type in ("revolute", "continuous"):
            return trimesh.transformations.rotation_matrix(q, self.unit_axis)
        return np.eye(4)


@dataclass
class Handle:
    """Where a robot grasps a movable part: ``position_link`` (3,) in the part's link
    frame, ``axis`` (3,) the unit direction of the bar in the object frame, ``kind``
    one of :data:`HANDLE_KINDS`."""

    position_link: np.ndarray
    axis: np.ndarray = field(default_factory=lambda: np.array([0.0, 0.0, 1.0]))
    kind: str = "none"

    def __post_init__(self) -> None:
        self.position_link = np.asarray(self.position_link, dtype=float).reshape(3)
        self.axis = np.asarray(self.axis, dtype=float).reshape(3)


@dataclass(frozen=True)
class MovablePart:
    """A movable part as the tasks need it (a read-only view of a joint and its handle).

    ``lower``/``upper`` are the joint limits (``lower`` = closed; metres or radians);
    ``axis`` and ``origin`` are the joint's axis and pivot in the object frame at rest;
    ``handle_link`` is the grasp point in the part's link frame, ``handle_object`` the
    same point in the object frame at rest, ``handle_axis`` the bar direction in the
    object frame, ``handle_kind`` one of :data:`HANDLE_KINDS`.
    """

    name: str
    joint_name: str
    joint_type: str
    lower: float
    upper: float
    axis: tuple[float, float, float]
    origin: tuple[float, float, float]
    handle_link: tuple[float, float, float]
    handle_object: tuple[float, float, float]
    handle_axis: tuple[float, float, float]
    handle_kind: str

    @property
    def range(self) -> float:
        return self.upper - self.lower

    @property
    def kind(self) -> str:
        """One of :data:`PART_KINDS`, from the joint and where the handle is from the hinge."""
        if self.joint_type == "prismatic":
            return "drawer"
        axis = np.asarray(self.axis, dtype=float)
        axis = axis / np.linalg.norm(axis)
        if abs(axis[2]) >= max(abs(axis[0]), abs(axis[1])):
            return "side_door"
        # the handle's offset from the hinge line: up (bottom door), down (top flap) or
        # level (a lid, hinged at an edge of its top)
        d = np.asarray(self.handle_object, dtype=float) - np.asarray(self.origin, dtype=float)
        d = d - (d @ axis) * axis
        level = float(np.linalg.norm(d[:2]))
        if d[2] > level:
            return "bottom_door"
        return "top_flap" if d[2] < -level else "lid"

    @property
    def handle_kind_onehot(self) -> tuple[float, ...]:
        """``handle_kind`` as a one-hot over :data:`HANDLE_KINDS` (all zero if unknown)."""
        return tuple(float(self.handle_kind == k) for k in HANDLE_KINDS)


def _triple(v: np.ndarray) -> tuple[float, float, float]:
    a = np.asarray(v, dtype=float).reshape(3)
    return (float(a[0]), float(a[1]), float(a[2]))


@dataclass
class BuiltAsset:
    """A built articulated asset: links, joints and handles, with its identity.

    ``folder`` is where it lives on disk (None while it is being built);
    ``bounds`` (2, 3) the object-frame box of its visual geometry at rest;
    ``metric_scale`` the metres per model unit the build applied; ``provenance`` where the
    object came from (the generator or importer and its version, the source photo, and
    where its category and motions came from), as the object model carried it.
    """

    id: str
    links: list[Link]
    joints: list[Joint]
    handles: dict[str, Handle] = field(default_factory=dict)
    category: str = "unknown"
    metric_scale: float = 1.0
    bounds: np.ndarray | None = None
    folder: Path | None = None
    provenance: dict[str, Any] = field(default_factory=dict)

    # ---- structure
    def link(self, name: str) -> Link:
        for link in self.links:
            if link.name == name:
                return link
        raise KeyError(f"no link named {name!r}; links: {[k.name for k in self.links]}")

    def joint(self, name: str) -> Joint:
        for j in self.joints:
            if j.name == name:
                return j
        raise KeyError(f"no joint named {name!r}; joints: {[j.name for j in self.joints]}")

    def joint_of(self, link: str) -> Joint | None:
        """The joint whose child is ``link`` (None for a root)."""
        return next((j for j in self.joints if j.child == link), None)

    @property
    def roots(self) -> list[str]:
        children = {j.child for j in self.joints}
        return [k.name for k in self.links if k.name not in children]

    @property
    def root(self) -> str:
        """The root link's name (the first root when the tree is malformed)."""
        roots = self.roots
        return roots[0] if roots else self.links[0].name

    @property
    def movable_joints(self) -> list[Joint]:
        return [j for j in self.joints if j.movable]

    @property
    def urdf_path(self) -> Path:
        if self.folder is None:
            raise ValueError(f"asset {self.id!r} has no folder yet")
        return self.folder / "model.urdf"

    def path_of(self, filename: str) -> Path:
        """The absolute path of a file the asset references (relative to its folder)."""
        if self.folder is None:
            raise ValueError(f"asset {self.id!r} has no folder yet")
        return self.folder / filename

    def friction_force(self, joint: Joint) -> float:
        """``joint``'s friction as a Coulomb force (N) or torque (N m), what MuJoCo's
        ``frictionloss`` and Newton's ``newton:friction`` mean: the asset's friction is the
        coefficient SAPIEN hands to PhysX, which scales it by the joint's load, about the
        carried part's weight (asset_pipeline.assets.rig), so coefficient x mass x g."""
        inertial = self.link(joint.child).inertial
        mass = inertial.mass if inertial is not None and math.isfinite(inertial.mass) else 0.0
        return float(joint.physics.friction) * max(mass, 0.0) * 9.81

    @property
    def joint_friction(self) -> dict[str, float]:
        """``friction`` of every joint, by name (SAPIEN's builder drops it: see sim_options)."""
        return {j.name: j.physics.friction for j in self.joints}

    # ---- kinematics
    def link_poses(self, qpos: Mapping[str, float] | None = None) -> dict[str, np.ndarray]:
        """(4, 4) pose of every link in the root (object) frame; joints not in ``qpos`` at
        ``lower``. Links not reachable from a root (a cycle) are left out."""
        qpos = qpos or {}
        poses: dict[str, np.ndarray] = {r: np.eye(4) for r in self.roots}
        pending = list(self.joints)
        while pending:
            rest = []
            for j in pending:
                if j.parent in poses:
                    q = float(qpos.get(j.name, j.lower))
                    poses[j.child] = poses[j.parent] @ j.origin @ j.motion(q)
                else:
                    rest.append(j)
            if len(rest) == len(pending):
                break
            pending = rest
        return poses

    # ---- the tasks' view
    def movable_parts(self) -> list[MovablePart]:
        """Every prismatic or revolute part with a handle, in joint order.

        Raises KeyError naming the part when a movable part has no handle.
        """
        rest = self.link_poses()
        out = []
        for j in self.joints:
            if j.type not in ("prismatic", "revolute"):
                continue
            h = self.handles.get(j.child)
            if h is None:
                raise KeyError(f"{j.child}: movable part without a handle")
            T = rest[j.child]
            joint_frame = rest[j.parent] @ j.origin
            out.append(
                MovablePart(
                    name=j.child,
                    joint_name=j.name,
                    joint_type=j.type,
                    lower=j.lower,
                    upper=j.upper,
                    axis=_triple(joint_frame[:3, :3] @ j.unit_axis),
                    origin=_triple(joint_frame[:3, 3]),
                    handle_link=_triple(h.position_link),
                    handle_object=_triple(T[:3, :3] @ h.position_link + T[:3, 3]),
                    handle_axis=_triple(h.axis),
                    handle_kind=h.kind,
                )
            )
        return out

    def parts_of_type(self, joint_type: str | None) -> list[MovablePart]:
        """:meth:`movable_parts` of one joint type (all of them for None)."""
        return [p for p in self.movable_parts() if joint_type is None or p.joint_type == joint_type]

    @property
    def joint_types(self) -> tuple[str, ...]:
        """Sorted distinct types of the movable joints."""
        return tuple(sorted({j.type for j in self.movable_joints}))

"""Physics rig of an articulated object: the object model becomes a built asset.

:func:`build_rig` turns a metric, watertight :class:`ArticulatedObject` and its
convex collision pieces into a :class:`~asset_pipeline.assets.built_asset.BuiltAsset`
(links with mass, centre of mass and inertia; joints with limits, damping and
friction; handles; file names by the built-asset layout of ``docs/architecture.md``).
It is the one place where the object model's joints and handles are converted; it
touches no file (:mod:`asset_pipeline.asset_io` writes the result).

Link frames: the ``base`` link frame is the object frame; a movable part's link
frame sits at its joint origin with axes parallel to the object frame, so
link-frame geometry = object-frame geometry - joint origin.

Physics defaults (:class:`PhysicsDefaults`, overridable per build)
-------------------------------------------------------------------
Mass: a shell model per ``Part.material`` (:class:`MaterialModel`) of the part's solid
(:func:`part_solid`: its primitives when it has them, else its mesh). Real furniture
and appliance parts are boards, sheet-metal skins around insulation, moulded
plastic and glass panes, not solid blocks of their material; a solid model made a
procedural refrigerator door 47 kg (real: 8-15 kg), too heavy for any gripper
once PhysX scales joint friction with the constraint load. With ``V`` the volume
and ``A`` the surface area of the (watertight) part mesh, a material of density
``rho`` and shell thickness ``t``::

    mass = rho * min(V, A * t) + rho_core * max(V - A * t, 0)

A slab thinner than ``2 t`` (``A * t >= V``) is solid; a thicker or hollow-looking
body is a skin of thickness ``t`` (the mesh surface counts both skins of a
double-walled panel: a fridge door's outer steel and its inner liner) around a core
of density ``rho_core`` (polyurethane foam in appliance panels, air otherwise).

=========  =====  =======  ======  ================================================
material   rho    t (mm)   core    note
=========  =====  =======  ======  ================================================
wood       600    19       0       particle board / pine; boards up to 38 mm solid
metal      7800   0.8      40      steel skins 0.5-1.0 mm, PU-foam insulation
plastic    1000   3        0       moulded ABS / PP walls
glass      2500   3        0       a pane of up to 6 mm is solid; two 3 mm panes
=========  =====  =======  ======  ================================================

Typical masses of procedural parts (seeds 0-5, median): refrigerator door ~10 kg,
dishwasher door ~5 kg, oven door ~7 kg, microwave door ~1 kg, cabinet door ~2 kg,
drawers 2-6 kg; bases: refrigerator ~80 kg, oven ~37 kg, microwave ~12 kg.

Inertia is consistent with that mass distribution: a solid part has the
uniform-density inertia of its volume; a shell has the inertia of an area density
``rho * t`` spread over its surface (exact per-triangle second moments) plus the
uniform inertia of its core, combined about the common centre of mass. Both are
real mass distributions, so the tensor is positive definite and satisfies the
triangle inequality up to round-off (:func:`sanitize_inertia` guards it).

Joint defaults (SI: N s/m and N for prismatic, N m s/rad and N m for revolute):

=========  =======  ========  ======  ==============
type       damping  friction  effort  velocity
=========  =======  ========  ======  ==============
prismatic  2.0      0.1       100     1.0 m/s
revolute   0.5      0.02      100     2.0 rad/s
=========  =======  ========  ======  ==============

A drawer heavier than 15 kg gets a lower friction coefficient, at most
``max_slide_friction / (m g)`` (15 N: SAPIEN's friction is the coefficient times the
load, see below), so that a hand's pull opens it.

Damping is capped at ``I / min_damping_time`` (0.01 s), ``I`` the mass (prismatic) or
the moment of inertia about the hinge (revolute): a part that small (a 5 cm flap of a
generated object, I ~ 5e-5 kg m^2) would otherwise be damped a thousand times faster than
it moves, and no drive could swing it within seconds. Procedural parts weigh far more
(a 1 kg microwave door: I ~ 0.03 kg m^2, cap 3 N m s/rad), so the table holds for them.

URDF reads ``friction`` as a force (N) or torque (N m), and so does MuJoCo's
``frictionloss``; SAPIEN hands it to PhysX as a *coefficient* on the joint's
constraint load, so in SAPIEN a heavy or cantilevered part (a door hanging off its
hinge) feels more friction than the number suggests. Measured on the test cabinet
(tests/test_build.py) in SAPIEN: its 4 kg door pulled with 10 N at the free edge
opens 0.7 rad in 0.5 s, its 5 kg drawer pushed with 10 N opens 0.16 m in 0.5 s and
reaches its 0.3 m limit within 1 s; nothing at rest drifts.
"""

from __future__ import annotations

import logging
from collections.abc import Mapping
from dataclasses import dataclass, field, replace

import numpy as np
import trimesh

from asset_pipeline.assets.built_asset import (
    BuiltAsset,
    CollisionPiece,
    Handle,
    Inertial,
    Joint,
    JointPhysics,
    Link,
    Visual,
)
from generator.articulated import ArticulatedObject, Part
from generator.articulated import Handle as ObjectHandle

log = logging.getLogger(__name__)

GRAVITY = 9.81  # m/s^2

#: A fallback handle sits this far (fraction of the part's width) in from the edge
#: opposite the hinge, but at most HANDLE_INSET_MAX metres.
HANDLE_INSET_FRACTION = 0.15
HANDLE_INSET_MAX = 0.05


@dataclass(frozen=True)
class MaterialModel:
    """How a material fills a part (see the module docstring).

    ``density`` (kg/m^3) of the material itself; ``shell_thickness`` (m) of its skin,
    ``None`` for solid; ``core_density`` (kg/m^3) of what fills a shell (0: air).
    """

    density: float
    shell_thickness: float | None = None
    core_density: float = 0.0


MATERIALS: dict[str, MaterialModel] = {
    "wood": MaterialModel(density=600.0, shell_thickness=0.019),
    "metal": MaterialModel(density=7800.0, shell_thickness=0.0008, core_density=40.0),
    "plastic": MaterialModel(density=1000.0, shell_thickness=0.003),
    "glass": MaterialModel(density=2500.0, shell_thickness=0.003),
}
#: Density (kg/m^3) of each material itself (a solid part of it).
DENSITIES: dict[str, float] = {k: m.density for k, m in MATERIALS.items()}


@dataclass(frozen=True)
class PhysicsDefaults:
    """Materials and joint physics used when building an asset (see the module docstring)."""

    materials: Mapping[str, MaterialModel] = field(default_factory=lambda: dict(MATERIALS))
    default_material: str = "wood"
    prismatic: JointPhysics = JointPhysics(damping=2.0, friction=0.1, effort=100.0, velocity=1.0)
    revolute: JointPhysics = JointPhysics(damping=0.5, friction=0.02, effort=100.0, velocity=2.0)
    #: Lower bound on a link's mass (kg); lighter links are scaled up (inertia too).
    min_mass: float = 0.05
    #: Joint damping is capped at (inertia about the joint) / this (s): see the docstring.
    min_damping_time: float = 0.01
    #: A door on a horizontal hinge gets at least this times its largest gravity lever
    #: (m) over its first ``hold_window`` radians as friction, so that a touch does not
    #: swing it open (see :func:`gravity_lever`); a wider window would need a friction
    #: that a hand's pull could not beat (SAPIEN's friction grows with the pull).
    hold_safety: float = 1.5
    hold_window: float = 0.2
    #: ... but no more friction than this.
    max_hold_friction: float = 1.0
    #: A drawer's friction is lowered so that what SAPIEN makes of it (the coefficient
    #: times the drawer's weight) stays at most this (N): a drawer the layout makes long
    #: and heavy (a deep desk's, 30-40 kg) would otherwise not open to a hand's pull.
    max_slide_friction: float = 15.0

    def material(self, material: str) -> MaterialModel:
        """The :class:`MaterialModel` of ``material`` (the default material's if unknown)."""
        if material not in self.materials:
            log.warning("unknown material %r; using %r", material, self.default_material)
            return self.materials[self.default_material]
        return self.materials[material]

    def density(self, material: str) -> float:
        """Density (kg/m^3) of ``material`` itself."""
        return float(self.material(material).density)

    def joint(self, joint_type: str) -> JointPhysics:
        if joint_type == "prismatic":
            return self.prismatic
        if joint_type == "revolute":
            return self.revolute
        return JointPhysics(damping=0.0, friction=0.0, effort=0.0, velocity=0.0)


# --------------------------------------------------------------------------- mass


@dataclass
class MassProperties:
    """Mass (kg), centre of mass (3,) in metres and inertia (3, 3) in kg m^2 about the COM."""

    mass: float
    com: np.ndarray
    inertia: np.ndarray


def sanitize_inertia(inertia: np.ndarray, rel_eps: float = 1e-4) -> np.ndarray:
    """Nearest physical inertia tensor (3, 3): symmetric, positive definite, triangle inequality.

    Principal moments below ``rel_eps * max`` are raised to it; when one moment
    exceeds the sum of the other two (only possible through round-off or clamping),
    the other two are raised to restore ``I_i <= I_j + I_k``.
    """
    inertia = 0.5 * (np.asarray(inertia, dtype=float) + np.asarray(inertia, dtype=float).T)
    eig, vec = np.linalg.eigh(inertia)
    top = max(float(eig.max()), 1e-12)
    eig = np.maximum(eig, rel_eps * top)
    for i in range(3):
        others = [j for j in range(3) if j != i]
        excess = eig[i] - eig[others].sum()
        if excess > 0:
            eig[others] += 0.5 * excess * (1 + 1e-9) + 1e-15
    out = (vec * eig) @ vec.T
    out[np.abs(out) < 1e-12 * eig.max()] = 0.0  # round-off products of the eigenbasis
    return 0.5 * (out + out.T)


def _solid(mesh: trimesh.Trimesh) -> trimesh.Trimesh:
    """The union of a closed multi-body mesh (overlaps counted once), else the mesh."""
    if mesh.body_count <= 1:
        return mesh
    try:
        bodies = mesh.split(only_watertight=False)
        union = trimesh.boolean.union(bodies, engine="manifold")
        if union.is_volume and union.volume > 0:
            return union
    except Exception as e:  # noqa: BLE001 - the plain mesh is a fine fallback
        log.debug("union of %d bodies failed: %s", mesh.body_count, e)
    return mesh


def surface_second_moments(mesh: trimesh.Trimesh) -> tuple[float, np.ndarray, np.ndarray]:
    """Area (m^2), area centroid (3,) and inertia (3, 3) about it of ``mesh``'s surface
    at unit area density (kg/m^2 = 1).

    Exact per triangle: the second moment of a triangle with vertices ``v_i`` and area
    ``a`` is ``a / 12 * (sum v_i v_i^T + s s^T)`` with ``s = sum v_i``.
    """
    tri = np.asarray(mesh.triangles, dtype=float)  # (F, 3, 3)
    area = np.asarray(mesh.area_faces, dtype=float)
    total = float(area.sum())
    if not total > 0:
        return 0.0, np.zeros(3), np.zeros((3, 3))
    centroid = (area[:, None] * tri.mean(axis=1)).sum(axis=0) / total
    t = tri - centroid  # about the centroid: better conditioned
    s = t.sum(axis=1)
    second = np.einsum("f,fvi,fvj->ij", area, t, t) + np.einsum("f,fi,fj->ij", area, s, s)
    second /= 12.0
    inertia = np.trace(second) * np.eye(3) - second
    return total, centroid, inertia


def _combine(parts: list[tuple[float, np.ndarray, np.ndarray]]) -> MassProperties:
    """Mass properties of bodies given as (mass, com, inertia about their com)."""
    parts = [p for p in parts if p[0] > 0]
    mass = float(sum(m for m, _, _ in parts))
    com = sum(m * c for m, c, _ in parts) / mass
    inertia = np.zeros((3, 3))
    for m, c, inertia_c in parts:
        d = c - com
        inertia = inertia + inertia_c + m * (float(d @ d) * np.eye(3) - np.outer(d, d))
    return MassProperties(mass=mass, com=np.asarray(com, dtype=float), inertia=inertia)


def mass_properties(
    mesh: trimesh.Trimesh, material: MaterialModel | float, min_mass: float = 0.0
) -> MassProperties:
    """Mass properties of a closed ``mesh`` (metres) made of ``material``.

    ``material``: a :class:`MaterialModel` (shell model, see the module docstring) or a
    plain density (kg/m^3) for a solid of uniform density. Overlapping closed bodies
    are unioned first (manifold3d) so overlaps count once. The COM is in the mesh's
    frame; the inertia is about the COM and sanitized by :func:`sanitize_inertia`. A
    mesh lighter than ``min_mass`` is scaled up to it.
    """
    if not isinstance(material, MaterialModel):
        material = MaterialModel(density=float(material))
    solid = _solid(mesh)
    volume = float(solid.volume)
    if not volume > 0:
        log.warning("mesh volume %.3g is not positive; using its convex hull", volume)
        solid = solid.convex_hull
        volume = float(solid.volume)
    rho, t = material.density, material.shell_thickness
    # trimesh: moment_inertia is about the centre of mass for density 1
    vol_com = np.asarray(solid.center_mass, dtype=float)
    vol_inertia = np.asarray(solid.moment_inertia, dtype=float)
    area = float(solid.area)
    if t is None or area * t >= volume:  # solid: a board, a pane, a moulded block
        mp = MassProperties(mass=volume * rho, com=vol_com, inertia=vol_inertia * rho)
    else:  # a skin of thickness t on the surface around a core
        area, surf_com, surf_inertia = surface_second_moments(solid)
        shell_density = rho * t  # kg/m^2
        core_volume = max(volume - area * t, 0.0)
        mp = _combine(
            [
                (area * shell_density, surf_com, surf_inertia * shell_density),
                (
                    core_volume * material.core_density,
                    vol_com,
                    vol_inertia * (core_volume / volume) * material.core_density,
                ),
            ]
        )
    if mp.mass < min_mass:
        mp.inertia = mp.inertia * (min_mass / max(mp.mass, 1e-12))
        mp.mass = min_mass
    mp.inertia = sanitize_inertia(mp.inertia)
    return mp


def mean_rgba(mesh: trimesh.Trimesh) -> np.ndarray:
    """(4,) mean colour of ``mesh`` in [0, 1] (area-agnostic vertex mean; grey if uncoloured)."""
    try:
        vis = mesh.visual
        if vis.kind == "texture":
            vis = vis.to_color()
        if vis.kind in ("vertex", "face"):
            return np.asarray(vis.vertex_colors, dtype=float).mean(axis=0) / 255.0
    except Exception as e:  # noqa: BLE001 - colour is cosmetic
        log.debug("no colour: %s", e)
    return np.array([0.7, 0.7, 0.7, 1.0])


# --------------------------------------------------------------------------- object -> asset


def link_origin(obj: ArticulatedObject, part_name: str) -> np.ndarray:
    """(3,) origin of a part's link frame in the object frame (zero for the base)."""
    p = obj.part(part_name)
    return np.zeros(3) if p.joint is None else np.asarray(p.joint.origin, dtype=float)


def joint_inertia(mp: MassProperties, joint_type: str, axis: np.ndarray) -> float:
    """What a joint's damping acts against: the mass (prismatic) or the moment of inertia
    about the joint axis (revolute; ``mp.com`` relative to a point on the axis)."""
    if joint_type != "revolute":
        return float(mp.mass)
    off = mp.com - axis * float(mp.com @ axis)
    return float(axis @ mp.inertia @ axis + mp.mass * (off @ off))


def gravity_lever(com: np.ndarray, axis: np.ndarray, lower: float, upper: float) -> float:
    """Largest lever (m) with which gravity opens a part about its hinge: the largest
    ``a . (r x -z)`` (positive: toward opening, as positive joint values open) with ``r``
    the centre of mass (3,) relative to a point on the hinge (link frame at ``lower``),
    turned to 17 angles from ``lower`` to ``upper``. Zero for a vertical hinge and for a
    lid that gravity pulls shut.

    SAPIEN scales joint friction by the joint's load (about the part's weight: see the
    module docstring), so a friction of about this lever holds the part open that far.
    """
    levers = [0.0]
    for q in np.linspace(lower, upper, 17):
        R = trimesh.transformations.rotation_matrix(float(q) - lower, axis)[:3, :3]
        levers.append(float(axis @ np.cross(R @ com, [0.0, 0.0, -1.0])))
    return max(levers)


def part_solid(part: Part) -> trimesh.Trimesh:
    """The solid a part's mass comes from: its primitives when it has them (a procedural
    part's exact solids, or a generated part's layout box: what the simulator collides
    with), else its watertight mesh."""
    if not part.primitives:
        return part.mesh
    return trimesh.util.concatenate([q.to_mesh() for q in part.primitives])


def fallback_handle(part: Part) -> ObjectHandle:
    """Grasp point of a movable part without a modelled handle (object frame, kind ``none``).

    The centre of the part's front face (the +x side of the bounding box of its solid,
    :func:`part_solid`: what it collides with), moved in the face plane away from the
    hinge line toward the opposite edge, stopping
    ``min(HANDLE_INSET_FRACTION * extent, HANDLE_INSET_MAX)`` short of it. Prismatic
    parts keep the face centre. The handle axis is the hinge axis for revolute
    parts (a bar parallel to the hinge) and +y otherwise.
    """
    lo, hi = part_solid(part).bounds
    centre = np.array([hi[0], 0.5 * (lo[1] + hi[1]), 0.5 * (lo[2] + hi[2])])
    j = part.joint
    if j is None or j.type != "revolute":
        return ObjectHandle(position=centre, axis=np.array([0.0, 1.0, 0.0]), kind="none")
    axis = np.asarray(j.axis, dtype=float)
    away = centre - j.origin
    away -= axis * float(away @ axis)  # perpendicular to the hinge line
    away[0] = 0.0  # stay on the front face
    n = float(np.linalg.norm(away))
    if n < 1e-9:
        return ObjectHandle(position=centre, axis=axis, kind="none")
    d = away / n
    half = 0.5 * (hi - lo)
    reach = float(np.abs(d) @ half)  # distance from the centre to the bbox edge along d
    inset = min(HANDLE_INSET_FRACTION * 2 * reach, HANDLE_INSET_MAX)
    return ObjectHandle(position=centre + d * max(reach - inset, 0.0), axis=axis, kind="none")


def textured_for_render(mesh: trimesh.Trimesh) -> trimesh.Trimesh:
    """``mesh`` with its vertex colours baked into a palette texture.

    SAPIEN's renderer ignores glTF vertex colours (COLOR_0) but draws base-colour
    textures, so coloured visuals are written textured; textured meshes pass through.
    """
    if mesh.visual.kind not in ("vertex", "face"):
        return mesh
    out = mesh.copy()
    out.visual = mesh.visual.to_texture()
    return out


def _in_link_frame(mesh: trimesh.Trimesh, origin: np.ndarray) -> trimesh.Trimesh:
    out = mesh.copy()
    out.apply_translation(-np.asarray(origin, dtype=float))
    return out


def build_rig(
    obj: ArticulatedObject,
    pieces: Mapping[str, list[trimesh.Trimesh]],
    name: str,
    physics: PhysicsDefaults = PhysicsDefaults(),
    visuals: Mapping[str, trimesh.Trimesh] | None = None,
) -> BuiltAsset:
    """The built asset of a metric, watertight ``obj`` whose part ``p`` collides as the
    convex ``pieces[p]`` (object frame) and looks like ``visuals[p]`` (object frame;
    default its own mesh).

    This is where the object model's parts, joints and handles become the built
    asset's links, joints and handles (the only such conversion). Base link first,
    then parts in object order; meshes are moved into their link frames and kept in
    memory for :func:`asset_pipeline.asset_io.save_asset`. File names follow the
    built-asset layout: ``visual/<part>.glb`` (+ ``.obj``), ``collision/<part>_<k>.obj``.
    """
    links, joints, handles = [], [], {}
    order = [obj.base] + [p for p in obj.parts if not p.is_base]
    for p in order:
        origin = link_origin(obj, p.name)
        mp = mass_properties(part_solid(p), physics.material(p.material), physics.min_mass)
        mp.com = mp.com - origin
        links.append(
            Link(
                name=p.name,
                semantic=p.semantic,
                material=p.material,
                inertial=Inertial(mass=mp.mass, com=mp.com, inertia=mp.inertia),
                visuals=[
                    Visual(
                        filename=f"visual/{p.name}.glb",
                        name=f"{p.name}_visual",
                        mesh=textured_for_render(
                            _in_link_frame((visuals or {}).get(p.name, p.mesh), origin)
                        ),
                    )
                ],
                collisions=[
                    CollisionPiece(
                        filename=f"collision/{p.name}_{k}.obj",
                        name=f"{p.name}_collision_{k}",
                        mesh=_in_link_frame(piece, origin),
                    )
                    for k, piece in enumerate(pieces[p.name])
                ],
                rgba=mean_rgba(p.mesh),
            )
        )
        if p.joint is None:
            continue
        j = p.joint
        axis = np.asarray(j.axis, dtype=float)
        axis = axis / np.linalg.norm(axis)
        joint_physics = physics.joint(j.type)
        cap = joint_inertia(mp, j.type, axis) / physics.min_damping_time
        if joint_physics.damping > cap:  # a small part: its damping time >= the floor
            joint_physics = replace(joint_physics, damping=cap)
        if j.type == "revolute":
            lever = gravity_lever(
                mp.com, axis, j.lower, min(j.upper, j.lower + physics.hold_window)
            )
            hold = min(physics.max_hold_friction, physics.hold_safety * lever)
            if hold > joint_physics.friction:  # a bottom-hinged door, a lid
                joint_physics = replace(joint_physics, friction=hold)
        elif j.type == "prismatic":
            slide = physics.max_slide_friction / max(mp.mass * GRAVITY, 1e-9)
            if joint_physics.friction > slide:
                joint_physics = replace(joint_physics, friction=slide)
        pivot = np.eye(4)
        pivot[:3, 3] = origin - link_origin(obj, j.parent)
        joints.append(
            Joint(
                name=f"joint_{p.name}",
                type=j.type,
                parent=j.parent,
                child=p.name,
                origin=pivot,
                axis=axis,
                lower=j.lower,
                upper=j.upper,
                physics=joint_physics,
            )
        )
        if j.movable:
            h = p.handle if p.handle is not None else fallback_handle(p)
            handles[p.name] = Handle(
                position_link=np.asarray(h.position, dtype=float) - origin,
                axis=np.asarray(h.axis, dtype=float),
                kind=h.kind,
            )
    return BuiltAsset(
        id=name,
        links=links,
        joints=joints,
        handles=handles,
        category=obj.category,
        metric_scale=float(obj.provenance.get("metric_scale", obj.scale or 1.0)),
        bounds=obj.bounds(),
        provenance=dict(obj.provenance),
    )

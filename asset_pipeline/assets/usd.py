"""``model.usdc``: the one writer of a built asset's OpenUSD stage with UsdPhysics.

:func:`usd_stage` makes the stage of a :class:`~asset_pipeline.assets.built_asset.BuiltAsset`
in memory, :func:`write_usd` writes it next to ``model.urdf`` (called by
:func:`asset_pipeline.assets.folder.save_asset` when the ``usd`` format is asked for).
It is written from the model, not converted from the URDF, and is never read back by
the pipeline (validation reads it with USD's own parser, :mod:`asset_pipeline.validate.usd_checks`).

The stage (docs/usd.md)::

    /<id>                    Xform, ArticulationRootAPI (the default prim)
      <link>                 Xform at the link's rest pose, RigidBodyAPI + MassAPI
        visual[_k]           Mesh, the visual in the link frame, texture coordinates ``st``,
                             bound to a UsdPreviewSurface reading ``visual/<link>.png``
        collision_<k>        Mesh (purpose guide), CollisionAPI + MeshCollisionAPI
                             "convexHull": one convex piece of ``collision/<link>_<k>.obj``
      joints/
        root_joint           FixedJoint: the base fixed to the world (SAPIEN's and the
                             MJCF's fixed root)
        joint_<part>         PrismaticJoint / RevoluteJoint (limits in metres / degrees)
      Looks/                 the preview materials and the physics material of every collider

Units: metres (``metersPerUnit`` 1), kilograms (``kilogramsPerUnit`` 1), Z up; USD's
angular quantities are in degrees. The stage's meshes are inline, and the texture is
the visual's ``visual/<link>.png`` (the one the MJCF maps), referenced, never copied.
One crate file (``.usdc``): on the bundled examples the same stage as text (``.usda``) is
3.6 times larger (2.8 MB against 0.76 MB, most of it the 60000 visual triangles), and
``usdcat model.usdc`` prints the text when a person wants to read it.

Joint physics, for the readers that exist: every movable joint has a DriveAPI (force
drive, stiffness 0, damping = the joint's damping, max force = its effort, target = its
lower limit), which is how PhysX and Newton express a passive joint damper and what a
task turns into a position drive by giving it a stiffness and a target. Friction: the
asset's ``friction`` is the coefficient SAPIEN hands to PhysX (docs/architecture.md,
:mod:`asset_pipeline.assets.rig`), written as ``physxJoint:jointFriction`` (the same
PhysX coefficient), and as ``newton:friction`` the Coulomb force (N) or torque (N m)
it amounts to under the part's weight (coefficient x child mass x g), which is what
Newton and MuJoCo mean by joint friction. ``physxJoint:maxJointVelocity`` is the
joint's velocity limit (deg/s for a revolute joint).
"""

from __future__ import annotations

import logging
import math
import os
from pathlib import Path

import numpy as np
import trimesh

from asset_pipeline.assets.built_asset import BuiltAsset, Joint, Link, Visual
from asset_pipeline.assets.mesh_files import read_obj

log = logging.getLogger(__name__)

#: File name of the USD stage in a built asset folder.
USD_NAME = "model.usdc"
#: Friction material of every collider: SimOptions' (static, dynamic, restitution), the
#: one SAPIEN validation and the tasks load the asset with.
COLLIDER_MATERIAL = (0.6, 0.5, 0.0)

_JOINT_DRIVE = {"prismatic": "linear", "revolute": "angular", "continuous": "angular"}


def _pxr():
    from pxr import Gf, Sdf, Tf, Usd, UsdGeom, UsdPhysics, UsdShade, Vt

    return Gf, Sdf, Tf, Usd, UsdGeom, UsdPhysics, UsdShade, Vt


def prim_name(name: str) -> str:
    """The USD prim name of a link, joint or asset name (a valid identifier)."""
    from pxr import Tf

    # a PartNet id ("11846") keeps its digits: "_11846", not "_1846"
    return Tf.MakeValidIdentifier(f"_{name}" if name[:1].isdigit() else name)


def axis_frame(axis: np.ndarray) -> np.ndarray:
    """(3, 3) rotation taking +X to the unit ``axis`` (3,): USD joints move along X."""
    a = np.asarray(axis, dtype=float)
    a = a / np.linalg.norm(a)
    x = np.array([1.0, 0.0, 0.0])
    c = float(x @ a)
    if c > 1 - 1e-12:
        return np.eye(3)
    if c < -1 + 1e-12:
        return np.diag([-1.0, -1.0, 1.0])  # half a turn about Z
    v = np.cross(x, a)
    return trimesh.transformations.rotation_matrix(math.acos(c), v)[:3, :3]


def _quatf(R: np.ndarray):
    Gf = _pxr()[0]
    T = np.eye(4)
    T[:3, :3] = R
    w, x, y, z = trimesh.transformations.quaternion_from_matrix(T)
    return Gf.Quatf(float(w), float(x), float(y), float(z))


def principal_inertia(inertia: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """(diagonal (3,), rotation (3, 3) with det +1) of a symmetric inertia tensor (3, 3):
    ``inertia = R @ diag(d) @ R.T``, the columns of R the principal axes."""
    sym = 0.5 * (np.asarray(inertia, dtype=float) + np.asarray(inertia, dtype=float).T)
    d, R = np.linalg.eigh(sym)
    if np.linalg.det(R) < 0:
        R[:, 0] = -R[:, 0]
    return d, R


def _mesh_arrays(mesh: trimesh.Trimesh, T: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    v = np.asarray(mesh.vertices, dtype=float) @ T[:3, :3].T + T[:3, 3]
    return v, np.asarray(mesh.faces, dtype=np.int64)


def _read_obj_uv(path: Path) -> tuple[np.ndarray, np.ndarray, np.ndarray | None]:
    """(vertices (n, 3), faces (m, 3), uv (n, 2) or None) of a visual OBJ written by
    :func:`asset_pipeline.assets.mesh_files.obj_text` (triangles, one ``vt`` per ``v``)."""
    lines = Path(path).read_text().splitlines()

    def numbers(prefix: str, width: int, dtype: type) -> np.ndarray:
        rows = [line[len(prefix) :] for line in lines if line.startswith(prefix)]
        flat = " ".join(rows).replace("/", " ").split()
        return np.array(flat, dtype=dtype).reshape(len(rows), -1)[:, :width]

    verts = numbers("v ", 3, float)
    vt = numbers("vt ", 2, float)
    f = numbers("f ", 6, np.int64)
    if f.shape[1] == 6:  # "f a/a b/b c/c": the vertex indices
        f = f[:, ::2]
    uv = vt if len(vt) == len(verts) and len(vt) else None
    return verts, f - 1, uv


def _visual_geometry(
    asset: BuiltAsset, visual: Visual
) -> tuple[np.ndarray, np.ndarray, np.ndarray | None]:
    """(vertices in the link frame, faces, per-vertex uv or None) of a visual: the mesh
    in memory (a build), else its GLB, else its OBJ (an asset read from disk)."""
    if visual.mesh is not None:
        v, f = _mesh_arrays(visual.mesh, visual.origin)
        uv = getattr(visual.mesh.visual, "uv", None) if visual.texture else None
        uv = None if uv is None or len(uv) != len(v) else np.asarray(uv, dtype=float)
        return v, f, uv
    glb = _read_glb(asset.path_of(visual.filename))
    if glb is not None:
        v, f = _mesh_arrays(glb, visual.origin)
        uv = getattr(glb.visual, "uv", None)
        uv = None if uv is None or len(uv) != len(v) else np.asarray(uv, dtype=float)
        return v, f, uv if visual.texture else None
    v, f, uv = _read_obj_uv(asset.path_of(visual.obj_filename))
    v = v @ visual.origin[:3, :3].T + visual.origin[:3, 3]
    return v, f, uv if visual.texture else None


def _read_glb(path: Path) -> trimesh.Trimesh | None:
    """The one mesh of a visual GLB (binary: 2-3 times faster to read than its OBJ twin),
    None when the file is not one mesh."""
    if path.suffix.lower() != ".glb" or not path.is_file():
        return None
    loaded = trimesh.load(str(path), process=False)
    meshes = loaded.dump() if isinstance(loaded, trimesh.Scene) else [loaded]
    return meshes[0] if len(meshes) == 1 and isinstance(meshes[0], trimesh.Trimesh) else None


def _define_mesh(stage, path: str, verts: np.ndarray, faces: np.ndarray):
    _, _, _, _, UsdGeom, _, _, Vt = _pxr()
    mesh = UsdGeom.Mesh.Define(stage, path)
    points = Vt.Vec3fArray.FromNumpy(np.ascontiguousarray(verts, dtype=np.float32))
    mesh.CreatePointsAttr(points)
    mesh.CreateFaceVertexCountsAttr(Vt.IntArray.FromNumpy(np.full(len(faces), 3, np.int32)))
    mesh.CreateFaceVertexIndicesAttr(
        Vt.IntArray.FromNumpy(np.ascontiguousarray(faces.reshape(-1), dtype=np.int32))
    )
    mesh.CreateExtentAttr(UsdGeom.Mesh.ComputeExtent(points))
    mesh.CreateSubdivisionSchemeAttr(UsdGeom.Tokens.none)
    return mesh


def _preview_material(stage, path: str, rgba: np.ndarray, texture: str | None):
    """A UsdPreviewSurface material: the link's colour, or the texture through ``st``."""
    Gf, Sdf, _, _, _, _, UsdShade, _ = _pxr()
    material = UsdShade.Material.Define(stage, path)
    surface = UsdShade.Shader.Define(stage, f"{path}/PreviewSurface")
    surface.CreateIdAttr("UsdPreviewSurface")
    rgb = Gf.Vec3f(*[float(c) for c in np.clip(rgba[:3], 0, 1)])
    diffuse = surface.CreateInput("diffuseColor", Sdf.ValueTypeNames.Color3f)
    diffuse.Set(rgb)
    surface.CreateInput("roughness", Sdf.ValueTypeNames.Float).Set(0.8)
    surface.CreateInput("metallic", Sdf.ValueTypeNames.Float).Set(0.0)
    surface_out = surface.CreateOutput("surface", Sdf.ValueTypeNames.Token)
    material.CreateSurfaceOutput().ConnectToSource(surface_out)
    if texture:
        reader = UsdShade.Shader.Define(stage, f"{path}/st_reader")
        reader.CreateIdAttr("UsdPrimvarReader_float2")
        reader.CreateInput("varname", Sdf.ValueTypeNames.String).Set("st")
        st = reader.CreateOutput("result", Sdf.ValueTypeNames.Float2)
        image = UsdShade.Shader.Define(stage, f"{path}/texture")
        image.CreateIdAttr("UsdUVTexture")
        image.CreateInput("file", Sdf.ValueTypeNames.Asset).Set(Sdf.AssetPath(f"./{texture}"))
        image.CreateInput("st", Sdf.ValueTypeNames.Float2).ConnectToSource(st)
        image.CreateInput("sourceColorSpace", Sdf.ValueTypeNames.Token).Set("sRGB")
        image.CreateInput("wrapS", Sdf.ValueTypeNames.Token).Set("repeat")
        image.CreateInput("wrapT", Sdf.ValueTypeNames.Token).Set("repeat")
        image.CreateInput("fallback", Sdf.ValueTypeNames.Float4).Set(Gf.Vec4f(*rgb, 1.0))
        color = image.CreateOutput("rgb", Sdf.ValueTypeNames.Float3)
        diffuse.ConnectToSource(color)
    return material


def _physics_material(stage, path: str):
    _, _, _, _, _, UsdPhysics, UsdShade, _ = _pxr()
    material = UsdShade.Material.Define(stage, path)
    api = UsdPhysics.MaterialAPI.Apply(material.GetPrim())
    static, dynamic, restitution = COLLIDER_MATERIAL
    api.CreateStaticFrictionAttr(static)
    api.CreateDynamicFrictionAttr(dynamic)
    api.CreateRestitutionAttr(restitution)
    return material


def _body(stage, root: str, asset: BuiltAsset, link: Link, pose: np.ndarray, looks: dict):
    Gf, _, _, _, UsdGeom, UsdPhysics, UsdShade, Vt = _pxr()
    path = f"{root}/{prim_name(link.name)}"
    xform = UsdGeom.Xform.Define(stage, path)
    xform.AddTransformOp().Set(Gf.Matrix4d(pose.T.tolist()))
    prim = xform.GetPrim()
    UsdPhysics.RigidBodyAPI.Apply(prim)
    if link.inertial is not None:
        mass = UsdPhysics.MassAPI.Apply(prim)
        mass.CreateMassAttr(float(link.inertial.mass))
        mass.CreateCenterOfMassAttr(Gf.Vec3f(*[float(c) for c in link.inertial.com]))
        d, R = principal_inertia(link.inertial.inertia)
        mass.CreateDiagonalInertiaAttr(Gf.Vec3f(*[float(max(x, 0.0)) for x in d]))
        mass.CreatePrincipalAxesAttr(_quatf(R))
    for k, v in enumerate(link.visuals):
        verts, faces, uv = _visual_geometry(asset, v)
        mesh = _define_mesh(stage, f"{path}/visual" + ("" if k == 0 else f"_{k}"), verts, faces)
        mesh.CreateDisplayColorAttr([Gf.Vec3f(*[float(c) for c in np.clip(link.rgba[:3], 0, 1)])])
        texture = v.texture if uv is not None else None
        if uv is not None:
            st = UsdGeom.PrimvarsAPI(mesh).CreatePrimvar(
                "st", _pxr()[1].ValueTypeNames.TexCoord2fArray, UsdGeom.Tokens.vertex
            )
            st.Set(Vt.Vec2fArray.FromNumpy(np.ascontiguousarray(uv, dtype=np.float32)))
        key = texture or f"colour_{prim_name(link.name)}"
        if key not in looks:
            name = prim_name(Path(texture).stem if texture else key)
            looks[key] = _preview_material(stage, f"{root}/Looks/{name}", link.rgba, texture)
        UsdShade.MaterialBindingAPI.Apply(mesh.GetPrim()).Bind(looks[key])
    physics_material = looks["__physics__"]
    for k, piece in enumerate(link.collisions):
        mesh_data = (
            piece.mesh if piece.mesh is not None else read_obj(asset.path_of(piece.filename))
        )
        verts, faces = _mesh_arrays(mesh_data, piece.origin)
        mesh = _define_mesh(stage, f"{path}/collision_{k}", verts, faces)
        mesh.CreatePurposeAttr(UsdGeom.Tokens.guide)
        cprim = mesh.GetPrim()
        UsdPhysics.CollisionAPI.Apply(cprim)
        UsdPhysics.MeshCollisionAPI.Apply(cprim).CreateApproximationAttr(
            UsdPhysics.Tokens.convexHull
        )
        UsdShade.MaterialBindingAPI.Apply(cprim).Bind(
            physics_material, UsdShade.Tokens.weakerThanDescendants, "physics"
        )
    return path


def _joint(stage, root: str, asset: BuiltAsset, j: Joint, bodies: dict[str, str]) -> None:
    Gf, Sdf, _, _, _, UsdPhysics, _, _ = _pxr()
    path = f"{root}/joints/{prim_name(j.name)}"
    if j.type == "prismatic":
        joint = UsdPhysics.PrismaticJoint.Define(stage, path)
    elif j.type in ("revolute", "continuous"):
        joint = UsdPhysics.RevoluteJoint.Define(stage, path)
    else:
        joint = UsdPhysics.FixedJoint.Define(stage, path)
    joint.CreateBody0Rel().SetTargets([bodies[j.parent]])
    joint.CreateBody1Rel().SetTargets([bodies[j.child]])
    Ra = axis_frame(j.unit_axis) if j.movable else np.eye(3)
    joint.CreateLocalPos0Attr(Gf.Vec3f(*[float(c) for c in j.origin[:3, 3]]))
    joint.CreateLocalRot0Attr(_quatf(j.origin[:3, :3] @ Ra))
    joint.CreateLocalPos1Attr(Gf.Vec3f(0.0, 0.0, 0.0))
    joint.CreateLocalRot1Attr(_quatf(Ra))
    if not j.movable:
        return
    joint.CreateAxisAttr("X")
    angular = j.type != "prismatic"
    scale = math.degrees(1.0) if angular else 1.0  # USD angles are degrees
    if j.type != "continuous":
        joint.CreateLowerLimitAttr(float(j.lower) * scale)
        joint.CreateUpperLimitAttr(float(j.upper) * scale)
    prim = joint.GetPrim()
    drive = UsdPhysics.DriveAPI.Apply(prim, _JOINT_DRIVE[j.type])
    drive.CreateTypeAttr("force")
    drive.CreateStiffnessAttr(0.0)
    # drive gains are per degree for an angular drive
    drive.CreateDampingAttr(float(j.physics.damping) / scale)
    drive.CreateMaxForceAttr(float(j.physics.effort) if j.physics.effort > 0 else 3.4e38)
    drive.CreateTargetPositionAttr(float(j.lower) * scale)
    drive.CreateTargetVelocityAttr(0.0)
    prim.AddAppliedSchema("PhysxJointAPI")
    prim.CreateAttribute("physxJoint:jointFriction", Sdf.ValueTypeNames.Float).Set(
        float(j.physics.friction)
    )
    if j.physics.velocity > 0:
        prim.CreateAttribute("physxJoint:maxJointVelocity", Sdf.ValueTypeNames.Float).Set(
            float(j.physics.velocity) * scale
        )
    prim.AddAppliedSchema("NewtonJointAPI")
    prim.CreateAttribute("newton:friction", Sdf.ValueTypeNames.Float).Set(asset.friction_force(j))


def usd_stage(asset: BuiltAsset):
    """The :class:`pxr.Usd.Stage` (in memory) of ``asset``; see the module docstring.

    Meshes not held in memory are read from the asset's folder (visual OBJs with their
    texture coordinates, collision OBJs).
    """
    Gf, _, _, Usd, UsdGeom, UsdPhysics, _, _ = _pxr()
    stage = Usd.Stage.CreateInMemory()
    UsdGeom.SetStageUpAxis(stage, UsdGeom.Tokens.z)
    UsdGeom.SetStageMetersPerUnit(stage, 1.0)
    UsdPhysics.SetStageKilogramsPerUnit(stage, 1.0)
    root = f"/{prim_name(asset.id)}"
    top = UsdGeom.Xform.Define(stage, root)
    stage.SetDefaultPrim(top.GetPrim())
    Usd.ModelAPI(top.GetPrim()).SetKind("component")
    UsdPhysics.ArticulationRootAPI.Apply(top.GetPrim())
    info = {"pact:id": asset.id, "pact:category": asset.category}
    top.GetPrim().SetCustomData(info)
    UsdGeom.Scope.Define(stage, f"{root}/Looks")
    looks = {"__physics__": _physics_material(stage, f"{root}/Looks/collider_material")}
    poses = asset.link_poses()
    bodies = {
        link.name: _body(stage, root, asset, link, poses.get(link.name, np.eye(4)), looks)
        for link in asset.links
    }
    UsdGeom.Scope.Define(stage, f"{root}/joints")
    fixed = UsdPhysics.FixedJoint.Define(stage, f"{root}/joints/root_joint")
    fixed.CreateBody1Rel().SetTargets([bodies[asset.root]])
    base_pose = poses.get(asset.root, np.eye(4))
    fixed.CreateLocalPos0Attr(Gf.Vec3f(*[float(c) for c in base_pose[:3, 3]]))
    fixed.CreateLocalRot0Attr(_quatf(base_pose[:3, :3]))
    fixed.CreateLocalPos1Attr(Gf.Vec3f(0.0, 0.0, 0.0))
    fixed.CreateLocalRot1Attr(_quatf(np.eye(3)))
    for j in asset.joints:
        _joint(stage, root, asset, j, bodies)
    return stage


def write_usd(asset: BuiltAsset, folder: str | Path, name: str = USD_NAME) -> Path:
    """Write the stage of ``asset`` as ``folder/name`` (atomically); return its path.

    ``name``'s extension chooses the encoding (``.usda`` text, ``.usdc`` crate). The
    asset's mesh files and textures are read from ``folder`` when not in memory.
    """
    folder = Path(folder)
    if asset.folder is None:
        asset.folder = folder
    stage = usd_stage(asset)
    path = folder / name
    tmp = folder / f".{path.stem}.{os.getpid()}.tmp{path.suffix}"
    try:
        stage.GetRootLayer().Export(str(tmp))
        os.replace(tmp, path)
    finally:
        tmp.unlink(missing_ok=True)
    return path

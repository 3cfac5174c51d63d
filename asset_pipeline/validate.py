"""Prove a built asset in SAPIEN: static, load, kinematic and dynamic checks, repairs, report.

:func:`validate_asset` runs every check on a built asset folder (the layout of
``docs/architecture.md``), repairs what it can (:mod:`asset_pipeline.repair`),
re-checks after each round of repairs and writes ``report.json`` (and
``preview.png``, :mod:`asset_pipeline.preview`) into the folder.

Stages and checks (check name, what it measures, its tolerance in :class:`Tolerances`):

static (the URDF and the collision OBJs, no simulator)
    ``urdf``                  the URDF parses and every referenced file exists
    ``single_root``           exactly one link is nobody's child, every joint's links exist
    ``axis_unit``             each movable joint's axis is finite with norm 1 (``axis_norm``)
    ``limits_ordered``        finite limits with lower < upper
    ``mass_positive``         finite mass > 0 per link
    ``inertia_valid``         symmetric, positive definite, I_i <= I_j + I_k
    ``collision_hulls``       every piece has 4..255 vertices and is not flat (``hull_min_thickness``)
    ``hinge_on_part``         a revolute hinge line lies on the part's AABB surface (``hinge_offset``)
load (SAPIEN on CPU)
    ``sapien_load``           the articulation loads
    ``collision_shapes``      shapes per link == ``<collision>`` elements (SAPIEN drops uncookable ones)
    ``joint_matches_urdf``    type, limits and axis as written
kinematic (set joint values, PhysX contact generation between per-link probe bodies)
    ``rest_penetration``      all joints closed: deepest overlap between any two parts (``penetration``)
    ``open_penetration``      all joints open
    ``sweep_penetration``     one joint from lower to upper in ``sweep_steps`` steps, the others
                              closed and then open: deepest overlap of the moving part with anything
    ``drawer_engaged``        a prismatic part at its upper limit still overlaps the base along the
                              axis by ``min_engaged_fraction`` of its own length
    ``opens_outward``         opening moves the part's centroid away from the base's centroid
dynamic (PhysX CPU, ``SimOptions`` as the tasks use them)
    ``rest_drift``            base fixed, 2 s under gravity, no drive: |q - q0| (``drift_linear`` /
                              ``drift_angular``) and final joint speed
    ``finite``                no NaN or inf anywhere in the dynamic runs
    ``drive_reach``           a PD drive takes the joint to 90 % of its range and back (not jammed)
    ``free_base_stable``      base free on the floor: tilt and displacement after ``free_time``

PhysX never reports contacts between a link and its parent, so the kinematic
stage does not ask the articulation: it builds one free rigid body per link from
the same convex pieces in a separate probe scene, places them with the URDF's
forward kinematics and reads PhysX's contact separations (negative = overlap).
"""

from __future__ import annotations

import json
import logging
import math
import time
import xml.etree.ElementTree as ET
from collections.abc import Callable, Iterable, Mapping
from dataclasses import asdict, dataclass, field
from pathlib import Path
from typing import Any

import numpy as np
import trimesh

from generator.articulated import atomic_write_bytes

from .sim_options import DEFAULT_SIM_OPTIONS, SimOptions, apply_sim_options, configure_urdf_loader

log = logging.getLogger(__name__)

REPORT_SCHEMA = "pact.validation"
REPORT_VERSION = 1
URDF_NAME = "model.urdf"
STAGES = ("static", "load", "kinematic", "dynamic")


class AssetFormatError(ValueError):
    """The built asset cannot be read (missing or malformed URDF); the message says which file."""


# --------------------------------------------------------------------------- tolerances


@dataclass(frozen=True)
class Tolerances:
    """Every threshold of validation. Units: metres, radians, seconds, kg."""

    axis_norm: float = 1e-4
    inertia_rel: float = 1e-6
    hull_min_vertices: int = 4
    hull_max_vertices: int = 255
    #: Thinnest allowed extent (m) of a hull along its principal axes (flat = coplanar).
    hull_min_thickness: float = 1e-4
    #: Largest distance (m) of a revolute hinge line from its part's AABB surface.
    hinge_offset: float = 0.02
    limit_match: float = 1e-4
    sweep_steps: int = 10
    #: Deepest allowed overlap (m) between two parts.
    penetration: float = 0.005
    #: A drawer at its upper limit keeps this fraction of its length inside the base.
    min_engaged_fraction: float = 0.05
    #: Opening must move the part's centroid at least this much (m) away from the base's.
    outward_min: float = 1e-4
    settle_time: float = 2.0
    drift_linear: float = 1e-3
    drift_angular: float = math.radians(1.0)
    max_linear_velocity: float = 0.1
    max_angular_velocity: float = 1.0
    #: The drive goes to this fraction of the range, and back to lower.
    drive_fraction: float = 0.9
    #: Seconds allowed for each leg of the drive test.
    drive_time: float = 3.0
    #: Reached = within this fraction of the range of the target.
    drive_error: float = 0.05
    #: Natural frequency (Hz) of the PD test drive (critically damped).
    drive_frequency: float = 1.5
    free_time: float = 1.5
    free_tilt: float = math.radians(2.0)
    free_displacement: float = 0.01


DEFAULT_TOLERANCES = Tolerances()


# --------------------------------------------------------------------------- report


@dataclass
class Check:
    """One check on one subject (a link, a joint or the whole asset)."""

    name: str
    stage: str
    subject: str
    passed: bool
    value: Any = None
    tolerance: Any = None
    message: str = ""
    #: Extra measurements repairs need (worst pair, gravity torque, ...); JSON-able.
    details: dict[str, Any] = field(default_factory=dict)

    @property
    def key(self) -> str:
        return f"{self.name}[{self.subject}]"


@dataclass
class RepairRecord:
    """One repair applied to the asset files: what, where, before and after."""

    kind: str
    target: str
    before: Any
    after: Any
    reason: str
    round: int = 0
    files: list[str] = field(default_factory=list)


@dataclass
class Report:
    """Outcome of :func:`validate_asset`; ``to_json`` is the ``report.json`` content."""

    asset: str
    status: str  # "ok", "repaired", "failed"
    checks: list[Check]
    repairs: list[RepairRecord] = field(default_factory=list)
    rounds: list[dict[str, Any]] = field(default_factory=list)
    reasons: list[str] = field(default_factory=list)
    timings: dict[str, float] = field(default_factory=dict)
    preview: str | None = None
    tolerances: Tolerances = DEFAULT_TOLERANCES
    sim_options: SimOptions = DEFAULT_SIM_OPTIONS

    @property
    def ok(self) -> bool:
        return self.status in ("ok", "repaired")

    @property
    def failed_checks(self) -> list[Check]:
        return [c for c in self.checks if not c.passed]

    def check(self, name: str, subject: str | None = None) -> list[Check]:
        """Checks called ``name`` (on ``subject`` when given)."""
        return [c for c in self.checks if c.name == name and subject in (None, c.subject)]

    def to_json(self) -> dict[str, Any]:
        return {
            "schema": REPORT_SCHEMA,
            "version": REPORT_VERSION,
            "asset": self.asset,
            "status": self.status,
            "reasons": self.reasons,
            "checks": [_jsonable(asdict(c)) for c in self.checks],
            "repairs": [_jsonable(asdict(r)) for r in self.repairs],
            "rounds": _jsonable(self.rounds),
            "timings": {k: round(v, 4) for k, v in self.timings.items()},
            "preview": self.preview,
            "tolerances": _jsonable(asdict(self.tolerances)),
            "sim_options": _jsonable(asdict(self.sim_options)),
        }


def _jsonable(x: Any) -> Any:
    if isinstance(x, dict):
        return {str(k): _jsonable(v) for k, v in x.items()}
    if isinstance(x, (list, tuple)):
        return [_jsonable(v) for v in x]
    if isinstance(x, np.ndarray):
        return _jsonable(x.tolist())
    if isinstance(x, (np.floating, float)):
        v = float(x)
        return v if math.isfinite(v) else str(v)
    if isinstance(x, np.integer):
        return int(x)
    if isinstance(x, (np.bool_, bool)):
        return bool(x)
    return x


def write_report(report: Report, asset_dir: str | Path) -> Path:
    """Write ``report.json`` atomically (temporary file + rename); return its path."""
    path = Path(asset_dir) / "report.json"
    atomic_write_bytes(path, json.dumps(report.to_json(), indent=2).encode())
    return path


# --------------------------------------------------------------------------- URDF model


@dataclass
class PieceSpec:
    """One ``<collision>`` element: a mesh file and its pose (4x4) in the link frame."""

    path: Path
    filename: str
    origin: np.ndarray


@dataclass
class LinkSpec:
    name: str
    mass: float | None = None
    com: np.ndarray = field(default_factory=lambda: np.zeros(3))
    inertia: np.ndarray | None = None
    pieces: list[PieceSpec] = field(default_factory=list)


@dataclass
class JointSpec:
    name: str
    type: str
    parent: str
    child: str
    origin: np.ndarray
    axis: np.ndarray
    lower: float = 0.0
    upper: float = 0.0
    damping: float = 0.0
    friction: float = 0.0
    effort: float = 0.0
    velocity: float = 0.0

    @property
    def movable(self) -> bool:
        return self.type in ("prismatic", "revolute", "continuous")

    @property
    def unit_axis(self) -> np.ndarray:
        n = float(np.linalg.norm(self.axis))
        return self.axis / n if n > 0 and math.isfinite(n) else self.axis

    def motion(self, q: float) -> np.ndarray:
        """4x4 motion of the child in the joint frame at joint value ``q``."""
        if self.type == "prismatic":
            T = np.eye(4)
            T[:3, 3] = q * self.unit_axis
            return T
        if self.type in ("revolute", "continuous"):
            return trimesh.transformations.rotation_matrix(q, self.unit_axis)
        return np.eye(4)


@dataclass
class UrdfSpec:
    path: Path
    links: dict[str, LinkSpec]
    joints: dict[str, JointSpec]

    @property
    def roots(self) -> list[str]:
        children = {j.child for j in self.joints.values()}
        return [n for n in self.links if n not in children]

    @property
    def movable_joints(self) -> list[JointSpec]:
        return [j for j in self.joints.values() if j.movable]

    def joint_of(self, link: str) -> JointSpec | None:
        return next((j for j in self.joints.values() if j.child == link), None)

    def link_poses(self, qpos: Mapping[str, float] | None = None) -> dict[str, np.ndarray]:
        """4x4 pose of every link in the root (object) frame; missing joints at ``lower``."""
        qpos = qpos or {}
        poses: dict[str, np.ndarray] = {r: np.eye(4) for r in self.roots}
        pending = list(self.joints.values())
        while pending:
            rest = []
            for j in pending:
                if j.parent in poses:
                    q = float(qpos.get(j.name, j.lower))
                    poses[j.child] = poses[j.parent] @ j.origin @ j.motion(q)
                else:
                    rest.append(j)
            if len(rest) == len(pending):  # unreachable links (a cycle): leave them out
                break
            pending = rest
        return poses


def _floats(text: str | None, n: int, default: float = 0.0) -> np.ndarray:
    if text is None:
        return np.full(n, default)
    vals = [float(v) for v in text.split()]
    if len(vals) != n:
        raise ValueError(f"expected {n} numbers, got {text!r}")
    return np.array(vals)


def origin_matrix(el: ET.Element | None) -> np.ndarray:
    """4x4 of a URDF ``<origin xyz rpy>`` (rpy: fixed-axis roll, pitch, yaw)."""
    if el is None:
        return np.eye(4)
    xyz = _floats(el.get("xyz"), 3)
    rpy = _floats(el.get("rpy"), 3)
    T = trimesh.transformations.euler_matrix(*rpy, axes="sxyz")
    T[:3, 3] = xyz
    return T


def read_urdf(path: str | Path) -> UrdfSpec:
    """Parse the links, collision pieces, inertials and joints of a built asset's URDF."""
    path = Path(path)
    if not path.is_file():
        raise AssetFormatError(f"{path}: URDF not found (run `pact build` first)")
    try:
        root = ET.parse(path).getroot()
    except ET.ParseError as e:
        raise AssetFormatError(f"{path}: not valid XML: {e}") from e
    links: dict[str, LinkSpec] = {}
    joints: dict[str, JointSpec] = {}
    try:
        for el in root.findall("link"):
            link = LinkSpec(name=el.get("name", ""))
            inertial = el.find("inertial")
            if inertial is not None:
                m = inertial.find("mass")
                link.mass = float(m.get("value", "nan")) if m is not None else None
                o = inertial.find("origin")
                link.com = origin_matrix(o)[:3, 3]
                i = inertial.find("inertia")
                if i is not None:
                    g = {
                        k: float(i.get(k, "0")) for k in ("ixx", "ixy", "ixz", "iyy", "iyz", "izz")
                    }
                    link.inertia = np.array(
                        [
                            [g["ixx"], g["ixy"], g["ixz"]],
                            [g["ixy"], g["iyy"], g["iyz"]],
                            [g["ixz"], g["iyz"], g["izz"]],
                        ]
                    )
            for col in el.findall("collision"):
                mesh = col.find("geometry/mesh")
                if mesh is None:
                    raise AssetFormatError(
                        f"{path}: link {link.name}: only mesh collisions are supported"
                    )
                fn = mesh.get("filename", "")
                link.pieces.append(
                    PieceSpec(
                        path=path.parent / fn.removeprefix("package://"),
                        filename=fn,
                        origin=origin_matrix(col.find("origin")),
                    )
                )
            links[link.name] = link
        for el in root.findall("joint"):
            lim = el.find("limit")
            dyn = el.find("dynamics")
            axis_el = el.find("axis")
            j = JointSpec(
                name=el.get("name", ""),
                type=el.get("type", ""),
                parent=el.find("parent").get("link", ""),  # type: ignore[union-attr]
                child=el.find("child").get("link", ""),  # type: ignore[union-attr]
                origin=origin_matrix(el.find("origin")),
                axis=_floats(axis_el.get("xyz") if axis_el is not None else None, 3, 0.0)
                if axis_el is not None
                else np.array([1.0, 0.0, 0.0]),
                lower=float(lim.get("lower", "0")) if lim is not None else 0.0,
                upper=float(lim.get("upper", "0")) if lim is not None else 0.0,
                effort=float(lim.get("effort", "0")) if lim is not None else 0.0,
                velocity=float(lim.get("velocity", "0")) if lim is not None else 0.0,
                damping=float(dyn.get("damping", "0")) if dyn is not None else 0.0,
                friction=float(dyn.get("friction", "0")) if dyn is not None else 0.0,
            )
            joints[j.name] = j
    except (AttributeError, ValueError) as e:
        raise AssetFormatError(f"{path}: malformed link or joint: {e}") from e
    return UrdfSpec(path=path, links=links, joints=joints)


def read_obj_vertices(path: str | Path) -> np.ndarray:
    """(n, 3) vertex positions of an OBJ file (only ``v`` lines are read)."""
    verts = []
    with open(path) as f:
        for line in f:
            if line.startswith("v "):
                verts.append([float(v) for v in line.split()[1:4]])
    return np.array(verts, dtype=float).reshape(-1, 3)


def link_pieces(spec: UrdfSpec) -> dict[str, list[np.ndarray]]:
    """Vertices (n, 3) of every collision piece of every link, in the link frame."""
    out: dict[str, list[np.ndarray]] = {}
    for name, link in spec.links.items():
        pieces = []
        for p in link.pieces:
            v = read_obj_vertices(p.path)
            pieces.append(v @ p.origin[:3, :3].T + p.origin[:3, 3])
        out[name] = pieces
    return out


def _transform(T: np.ndarray, v: np.ndarray) -> np.ndarray:
    return v @ T[:3, :3].T + T[:3, 3]


def hull_thickness(v: np.ndarray) -> float:
    """Smallest extent (m) of a point set along its principal axes (0 for a flat set)."""
    if len(v) < 4:
        return 0.0
    c = v - v.mean(0)
    _, _, vt = np.linalg.svd(c, full_matrices=False)
    proj = c @ vt.T
    return float(np.ptp(proj, axis=0).min())


def link_centroid(pieces: list[np.ndarray]) -> np.ndarray:
    """Volume-weighted centroid (3,) of a link's convex pieces (mean of vertices if flat)."""
    total, acc = 0.0, np.zeros(3)
    for v in pieces:
        if len(v) < 4 or hull_thickness(v) < 1e-9:
            continue
        try:
            h = trimesh.convex.convex_hull(v)
            vol = float(abs(h.volume))
            acc += vol * np.asarray(h.center_mass)
            total += vol
        except Exception:  # noqa: BLE001 - qhull errors on degenerate input
            continue
    if total > 0:
        return acc / total
    allv = np.concatenate([v for v in pieces if len(v)] or [np.zeros((1, 3))])
    return allv.mean(0)


# --------------------------------------------------------------------------- static checks


def static_checks(spec: UrdfSpec, tol: Tolerances) -> list[Check]:
    """Checks on the URDF and the collision OBJs alone."""
    checks: list[Check] = []
    roots = spec.roots
    bad_refs = [
        f"{j.name}: {j.parent}->{j.child}"
        for j in spec.joints.values()
        if j.parent not in spec.links or j.child not in spec.links
    ]
    parents: dict[str, int] = {}
    for j in spec.joints.values():
        parents[j.child] = parents.get(j.child, 0) + 1
    multi = sorted(k for k, n in parents.items() if n > 1)
    ok = len(roots) == 1 and not bad_refs and not multi
    checks.append(
        Check(
            "single_root",
            "static",
            "asset",
            ok,
            value=roots,
            tolerance="exactly one root link",
            message=""
            if ok
            else f"roots {roots}; unknown links in {bad_refs}; several parents: {multi}",
        )
    )
    n_movable = len(spec.movable_joints)
    checks.append(
        Check(
            "has_movable_part",
            "static",
            "asset",
            n_movable > 0,
            value=n_movable,
            tolerance=">= 1 prismatic or revolute joint",
            message=""
            if n_movable
            else f"{spec.path.name} has {len(spec.links)} link(s) and no prismatic or revolute "
            "joint: nothing to articulate (the generator found no movable part; give a part "
            "mask, or check the input image)",
        )
    )
    for j in spec.movable_joints:
        n = float(np.linalg.norm(j.axis))
        ok = bool(np.isfinite(j.axis).all() and abs(n - 1.0) <= tol.axis_norm)
        checks.append(
            Check(
                "axis_unit",
                "static",
                j.name,
                ok,
                value=n,
                tolerance=tol.axis_norm,
                message="" if ok else f"axis {j.axis.tolist()} is not a finite unit vector",
            )
        )
        ok = bool(math.isfinite(j.lower) and math.isfinite(j.upper) and j.lower < j.upper)
        checks.append(
            Check(
                "limits_ordered",
                "static",
                j.name,
                ok,
                value=[j.lower, j.upper],
                tolerance="finite, lower < upper",
                message=""
                if ok
                else f"limits [{j.lower}, {j.upper}] are not finite and ordered "
                "(lower = closed); fix the joint range in object.json and rebuild",
            )
        )
    for link in spec.links.values():
        m = link.mass
        ok = m is not None and math.isfinite(m) and m > 0
        checks.append(
            Check(
                "mass_positive",
                "static",
                link.name,
                bool(ok),
                value=m,
                tolerance="> 0",
                message=""
                if ok
                else f"mass {m} must be finite and > 0 (SAPIEN would silently "
                "replace it from the collision shapes); rebuild with a material density",
            )
        )
        checks.append(_inertia_check(link, tol))
        checks.append(_hull_check(link, tol))
    pieces = None
    for j in spec.movable_joints:
        if j.type != "revolute" or j.child not in spec.links:
            continue
        if pieces is None:
            pieces = link_pieces(spec)
        checks.append(_hinge_check(j, pieces.get(j.child, []), tol))
    return checks


def _inertia_check(link: LinkSpec, tol: Tolerances) -> Check:
    inertia = link.inertia
    if inertia is None or not np.isfinite(inertia).all():
        return Check(
            "inertia_valid",
            "static",
            link.name,
            False,
            value=None,
            tolerance="positive definite, triangle inequality",
            message="missing or non-finite <inertia>",
        )
    eig = np.linalg.eigvalsh(0.5 * (inertia + inertia.T))
    scale = max(float(np.abs(eig).max()), 1e-12)
    pd = bool((eig > tol.inertia_rel * scale).all())
    tri = bool(
        all(
            eig[i] <= eig[(i + 1) % 3] + eig[(i + 2) % 3] + tol.inertia_rel * scale
            for i in range(3)
        )
    )
    ok = pd and tri
    msg = "" if ok else ("not positive definite" if not pd else "violates I_i <= I_j + I_k")
    return Check(
        "inertia_valid",
        "static",
        link.name,
        ok,
        value=eig.tolist(),
        tolerance="positive definite, triangle inequality",
        message=msg,
    )


def _hull_check(link: LinkSpec, tol: Tolerances) -> Check:
    bad: list[dict[str, Any]] = []
    counts, thick = [], []
    for k, p in enumerate(link.pieces):
        if not p.path.is_file():
            bad.append({"piece": k, "file": p.filename, "problem": "file not found"})
            continue
        try:
            v = read_obj_vertices(p.path)
        except (OSError, ValueError) as e:
            bad.append({"piece": k, "file": p.filename, "problem": f"unreadable: {e}"})
            continue
        n = len(v)
        t = hull_thickness(v) if n else 0.0
        counts.append(n)
        thick.append(t)
        if not tol.hull_min_vertices <= n <= tol.hull_max_vertices:
            bad.append({"piece": k, "file": p.filename, "problem": f"{n} vertices"})
        elif not np.isfinite(v).all():
            bad.append({"piece": k, "file": p.filename, "problem": "non-finite vertices"})
        elif t < tol.hull_min_thickness:
            bad.append({"piece": k, "file": p.filename, "problem": f"flat (thickness {t:.2e} m)"})
    ok = not bad and bool(link.pieces)
    value = {
        "pieces": len(link.pieces),
        "vertices": [min(counts), max(counts)] if counts else None,
        "min_thickness": min(thick) if thick else None,
    }
    msg = (
        ""
        if ok
        else (
            "no collision pieces"
            if not link.pieces
            else "; ".join(f"{b['file']}: {b['problem']}" for b in bad)
        )
    )
    return Check(
        "collision_hulls",
        "static",
        link.name,
        ok,
        value=value,
        tolerance={
            "vertices": [tol.hull_min_vertices, tol.hull_max_vertices],
            "min_thickness": tol.hull_min_thickness,
        },
        message=msg,
        details={"bad": bad},
    )


def hinge_offset(axis: np.ndarray, lo: np.ndarray, hi: np.ndarray) -> tuple[float, np.ndarray]:
    """Distance (m) of the hinge line (through the origin along ``axis``) from the AABB surface.

    Returns the distance and the point of the AABB surface closest to the line
    (the PAct post-processing target), both in the link frame. The line is
    represented by its point closest to the box centre.
    """
    a = axis / np.linalg.norm(axis)
    c = 0.5 * (lo + hi)
    p = (c @ a) * a  # point of the line closest to the centre
    inside = bool(np.all(p >= lo) & np.all(p <= hi))
    if not inside:
        q = np.clip(p, lo, hi)
        return float(np.linalg.norm(p - q)), q
    # inside: move to the nearest face among those not perpendicular to the axis
    best, target = math.inf, p
    for i in range(3):
        if abs(a[i]) > 0.999:  # a face perpendicular to the axis does not hold a hinge line
            continue
        for bound in (lo[i], hi[i]):
            d = abs(p[i] - bound)
            if d < best:
                best, target = d, p.copy()
                target[i] = bound
    return float(best), target


def _hinge_check(j: JointSpec, pieces: list[np.ndarray], tol: Tolerances) -> Check:
    if not pieces or not any(len(v) for v in pieces):
        return Check(
            "hinge_on_part", "static", j.name, False, message="part has no collision geometry"
        )
    allv = np.concatenate([v for v in pieces if len(v)])
    lo, hi = allv.min(0), allv.max(0)
    d, target = hinge_offset(j.unit_axis, lo, hi)
    ok = d <= tol.hinge_offset
    return Check(
        "hinge_on_part",
        "static",
        j.name,
        ok,
        value=d,
        tolerance=tol.hinge_offset,
        message="" if ok else f"hinge line is {d:.3f} m from the part's bounding box surface",
        details={"target_link": target.tolist(), "aabb": [lo.tolist(), hi.tolist()]},
    )


# --------------------------------------------------------------------------- SAPIEN loading


def physics_scene(options: SimOptions, timestep: float | None = None) -> Any:
    """A physics-only SAPIEN scene (CPU PhysX, no renderer) with the options' timestep."""
    import sapien

    scene = sapien.Scene([sapien.physx.PhysxCpuSystem()])
    scene.set_timestep(timestep or options.timestep)
    return scene


def load_physics(scene: Any, urdf: Path, options: SimOptions, fix_root: bool | None = None) -> Any:
    """Load the URDF's links, collisions and joints (visual meshes skipped) with ``options``.

    The mesh cache is cleared first: repaired OBJ files keep their names, and SAPIEN
    would otherwise reuse the shapes it cooked from the old contents.
    """
    import sapien

    sapien.physx.clear_cache()
    loader = scene.create_urdf_loader()
    configure_urdf_loader(loader, options)
    if fix_root is not None:
        loader.fix_root_link = fix_root
    builder = loader.load_file_as_articulation_builder(str(urdf))
    for lb in builder.link_builders:
        lb.visual_records = []
    art = builder.build()
    apply_sim_options(art, options, urdf=urdf)
    return art


_SAPIEN_TYPES = {
    "prismatic": ("prismatic",),
    "revolute": ("revolute", "revolute_unwrapped"),
    "continuous": ("revolute",),
    "fixed": ("fixed",),
}


def load_checks(spec: UrdfSpec, tol: Tolerances, options: SimOptions) -> list[Check]:
    """The articulation loads; shapes, joint types, limits and axes are as written."""
    scene = physics_scene(options)
    try:
        art = load_physics(scene, spec.path, options)
    except Exception as e:  # noqa: BLE001 - SAPIEN raises many types
        return [
            Check(
                "sapien_load",
                "load",
                "asset",
                False,
                value=str(e),
                tolerance="loads",
                message=f"SAPIEN cannot load the URDF: {e}",
            )
        ]
    checks = [Check("sapien_load", "load", "asset", True, value="loaded", tolerance="loads")]
    links = {link.name: link for link in art.links}
    for name, link in spec.links.items():
        n = len(links[name].collision_shapes) if name in links else 0
        ok = n == len(link.pieces)
        checks.append(
            Check(
                "collision_shapes",
                "load",
                name,
                ok,
                value=n,
                tolerance=len(link.pieces),
                message=""
                if ok
                else f"SAPIEN made {n} of {len(link.pieces)} collision shapes "
                "(it drops pieces it cannot cook)",
            )
        )
    sj = {j.name: j for j in art.get_joints()}
    for j in spec.movable_joints:
        s = sj.get(j.name)
        if s is None:
            checks.append(
                Check("joint_matches_urdf", "load", j.name, False, message="joint missing")
            )
            continue
        problems = []
        if s.type not in _SAPIEN_TYPES.get(j.type, ()):
            problems.append(f"type {s.type} != {j.type}")
        lim = np.asarray(s.limit, dtype=float).reshape(-1)
        if j.type != "continuous" and (
            abs(lim[0] - j.lower) > tol.limit_match or abs(lim[1] - j.upper) > tol.limit_match
        ):
            problems.append(f"limits {lim.tolist()} != [{j.lower}, {j.upper}]")
        ax = np.asarray(s.get_pose_in_parent().to_transformation_matrix())[:3, 0]
        want = j.origin[:3, :3] @ j.unit_axis
        if np.isfinite(want).all() and np.linalg.norm(ax - want) > 1e-3:
            problems.append(f"axis {ax.round(4).tolist()} != {want.round(4).tolist()}")
        checks.append(
            Check(
                "joint_matches_urdf",
                "load",
                j.name,
                not problems,
                value={"type": s.type, "limits": lim.tolist()},
                tolerance=tol.limit_match,
                message="; ".join(problems),
            )
        )
    return checks


# --------------------------------------------------------------------------- kinematic


class PenetrationProbe:
    """One free rigid body per link in a private PhysX scene, for overlap queries.

    :meth:`query` places every link at the given poses, runs PhysX contact
    generation (one tiny step, gravity off) and returns the deepest overlap of
    every pair of (link, piece) with a negative separation.
    """

    def __init__(self, pieces: Mapping[str, list[np.ndarray]]) -> None:
        import sapien

        self._sapien = sapien
        self.scene = sapien.Scene([sapien.physx.PhysxCpuSystem()])
        self.scene.set_timestep(1e-6)
        mat = sapien.physx.PhysxMaterial(0.0, 0.0, 0.0)
        self.bodies: dict[str, Any] = {}
        self.shape_ids: dict[int, tuple[str, int]] = {}
        self._keep: list[Any] = []
        for name, plist in pieces.items():
            ent = sapien.Entity()
            ent.name = name
            body = sapien.physx.PhysxRigidDynamicComponent()
            n = 0
            for k, v in enumerate(plist):
                if len(v) < 4 or not np.isfinite(v).all():
                    continue
                shape = sapien.physx.PhysxCollisionShapeConvexMesh(
                    np.asarray(v, dtype=np.float32), np.ones(3, dtype=np.float32), mat
                )
                shape.set_contact_offset(0.002)
                shape.set_rest_offset(0.0)
                body.attach(shape)
                self.shape_ids[id(shape)] = (name, k)
                self._keep.append(shape)
                n += 1
            if n == 0:
                continue
            body.disable_gravity = True
            ent.add_component(body)
            self.scene.add_entity(ent)
            self.bodies[name] = (ent, body)

    def query(self, poses: Mapping[str, np.ndarray]) -> list[dict[str, Any]]:
        """Overlapping piece pairs at ``poses`` (4x4 per link): link, piece, depth, normal."""
        for name, (ent, body) in self.bodies.items():
            ent.pose = self._sapien.Pose(np.asarray(poses[name], dtype=np.float32))
            body.linear_velocity = np.zeros(3)
            body.angular_velocity = np.zeros(3)
        self.scene.step()
        out: dict[tuple, dict[str, Any]] = {}
        for c in self.scene.get_contacts():
            if not c.points:
                continue
            a = self.shape_ids.get(id(c.shapes[0]))
            b = self.shape_ids.get(id(c.shapes[1]))
            if a is None or b is None or a[0] == b[0]:
                continue
            pt = min(c.points, key=lambda p: p.separation)
            depth = -float(pt.separation)
            if depth <= 0:
                continue
            (a, b) = sorted([a, b])
            key = (a, b)
            if key not in out or depth > out[key]["depth"]:
                out[key] = {
                    "links": [a[0], b[0]],
                    "pieces": [a[1], b[1]],
                    "depth": depth,
                    "normal": np.asarray(pt.normal, dtype=float).tolist(),
                    "position": np.asarray(pt.position, dtype=float).tolist(),
                }
        return sorted(out.values(), key=lambda d: -d["depth"])


def _worst(pairs: Iterable[dict[str, Any]], link: str | None = None) -> dict[str, Any] | None:
    sel = [p for p in pairs if link is None or link in p["links"]]
    return max(sel, key=lambda p: p["depth"]) if sel else None


def kinematic_checks(spec: UrdfSpec, tol: Tolerances) -> list[Check]:
    """Overlap at rest, open and along every joint's sweep; drawer engagement; outward motion."""
    pieces = link_pieces(spec)
    probe = PenetrationProbe(pieces)
    movable = spec.movable_joints
    closed = {j.name: j.lower for j in movable}
    opened = {j.name: j.upper for j in movable}
    checks: list[Check] = []
    for name, q in (("rest_penetration", closed), ("open_penetration", opened)):
        pairs = probe.query(spec.link_poses(q))
        w = _worst(pairs)
        depth = w["depth"] if w else 0.0
        bad = [p for p in pairs if p["depth"] > tol.penetration]
        checks.append(
            Check(
                name,
                "kinematic",
                "asset",
                not bad,
                value=depth,
                tolerance=tol.penetration,
                message=""
                if not bad
                else "; ".join(
                    f"{p['links'][0]}#{p['pieces'][0]} / {p['links'][1]}#{p['pieces'][1]} overlap "
                    f"{p['depth'] * 1000:.1f} mm"
                    for p in bad[:4]
                ),
                details={"pairs": bad, "qpos": q},
            )
        )
    base = spec.roots[0] if spec.roots else None
    base_centroid = link_centroid(pieces.get(base, [])) if base else np.zeros(3)
    base_all = np.concatenate([v for v in pieces.get(base, []) if len(v)] or [np.zeros((1, 3))])
    for j in movable:
        if not (math.isfinite(j.lower) and math.isfinite(j.upper) and j.lower < j.upper):
            continue  # already failed statically; a sweep would be meaningless
        worst: dict[str, Any] | None = None
        for mode, others in (("others_closed", closed), ("others_open", opened)):
            for q in np.linspace(j.lower, j.upper, tol.sweep_steps + 1):
                qpos = dict(others)
                qpos[j.name] = float(q)
                w = _worst(probe.query(spec.link_poses(qpos)), j.child)
                if w and (worst is None or w["depth"] > worst["depth"]):
                    worst = dict(w, q=float(q), mode=mode)
        depth = worst["depth"] if worst else 0.0
        ok = depth <= tol.penetration
        checks.append(
            Check(
                "sweep_penetration",
                "kinematic",
                j.name,
                ok,
                value=depth,
                tolerance=tol.penetration,
                message=""
                if ok
                else f"{worst['links'][0]} and {worst['links'][1]} overlap "  # type: ignore[index]
                f"{depth * 1000:.1f} mm at q={worst['q']:.3f} ({worst['mode']})",  # type: ignore[index]
                details={"worst": worst},
            )
        )
        child = [v for v in pieces.get(j.child, []) if len(v)]
        if not child:
            continue
        c_local = link_centroid(child)
        poses_closed = spec.link_poses(closed)
        c0 = _transform(poses_closed[j.child], c_local[None])[0]
        increase = []
        for frac in (0.1, 1.0):
            qpos = dict(closed)
            qpos[j.name] = j.lower + frac * (j.upper - j.lower)
            c1 = _transform(spec.link_poses(qpos)[j.child], c_local[None])[0]
            increase.append(
                float(np.linalg.norm(c1 - base_centroid) - np.linalg.norm(c0 - base_centroid))
            )
        # at least the full opening must move away; a first step inward is also a fault
        ok = increase[1] > tol.outward_min and increase[0] > -tol.outward_min
        checks.append(
            Check(
                "opens_outward",
                "kinematic",
                j.name,
                ok,
                value=increase[1],
                tolerance=tol.outward_min,
                message=""
                if ok
                else "opening moves the part toward the base's centre (axis inverted?)",
                details={"increase_at_10pct": increase[0], "increase_at_upper": increase[1]},
            )
        )
        if j.type == "prismatic":
            checks.append(_engagement_check(j, spec, child, base_all, opened, closed, tol))
    return checks


def _engagement_check(
    j: JointSpec,
    spec: UrdfSpec,
    child: list[np.ndarray],
    base_all: np.ndarray,
    opened: Mapping[str, float],
    closed: Mapping[str, float],
    tol: Tolerances,
) -> Check:
    qpos = dict(closed)
    qpos[j.name] = j.upper
    T = spec.link_poses(qpos)[j.child]
    parent_T = spec.link_poses(qpos)[j.parent]
    axis_w = parent_T[:3, :3] @ j.origin[:3, :3] @ j.unit_axis
    cv = _transform(T, np.concatenate(child)) @ axis_w
    bv = base_all @ axis_w
    length = float(np.ptp(cv))
    overlap = float(min(cv.max(), bv.max()) - max(cv.min(), bv.min()))
    frac = overlap / length if length > 0 else 0.0
    ok = frac >= tol.min_engaged_fraction
    return Check(
        "drawer_engaged",
        "kinematic",
        j.name,
        ok,
        value=frac,
        tolerance=tol.min_engaged_fraction,
        message=""
        if ok
        else f"at its upper limit the part keeps {overlap * 1000:.0f} mm "
        f"({frac:.0%}) of its {length * 1000:.0f} mm inside the base",
        details={"overlap": overlap, "length": length, "upper": j.upper, "lower": j.lower},
    )


# --------------------------------------------------------------------------- dynamic


def _effective_inertia(art: Any, joint: Any, jtype: str) -> float:
    """Mass (prismatic) or moment of inertia about the hinge (revolute) of the joint's child."""
    link = joint.child_link
    m = float(link.mass)
    if jtype == "prismatic":
        return max(m, 1e-3)
    jp = np.asarray(joint.get_global_pose().to_transformation_matrix())
    a, p = jp[:3, 0], jp[:3, 3]
    cm = np.asarray((link.entity_pose * link.cmass_local_pose).to_transformation_matrix())
    R = cm[:3, :3]
    inertia = R @ np.diag(np.asarray(link.inertia, dtype=float)) @ R.T
    r = cm[:3, 3] - p
    r_perp = r - (r @ a) * a
    return max(float(a @ inertia @ a + m * (r_perp @ r_perp)), 1e-5)


def dynamic_checks(spec: UrdfSpec, tol: Tolerances, options: SimOptions) -> list[Check]:
    """Rest under gravity, PD drive to 90 % and back, free base standing on the floor."""
    checks: list[Check] = []
    finite_ok, finite_where = True, []
    movable = spec.movable_joints
    dt = options.timestep
    scene = physics_scene(options)
    art = load_physics(scene, spec.path, options, fix_root=True)
    art.set_sleep_threshold(0.0)
    joints = {j.name: j for j in art.get_active_joints()}
    names = [j.name for j in art.get_active_joints()]
    spec_of = {j.name: j for j in movable}
    lower = np.array([spec_of[n].lower for n in names], dtype=float)
    art.set_qpos(lower.astype(np.float32))
    art.set_qvel(np.zeros(len(names), dtype=np.float32))
    # --- rest under gravity, no drive (the URDF's damping acts, as in the tasks)
    q0 = np.asarray(art.get_qpos(), dtype=float)
    tau = -np.asarray(art.compute_passive_force(True, False), dtype=float)  # gravity, at start
    masses = {n: float(joints[n].child_link.mass) for n in names}
    maxdev = np.zeros(len(names))
    for _ in range(round(tol.settle_time / dt)):
        scene.step()
        q = np.asarray(art.get_qpos(), dtype=float)
        if not np.isfinite(q).all():
            break
        maxdev = np.maximum(maxdev, np.abs(q - q0))
    q = np.asarray(art.get_qpos(), dtype=float)
    qd = np.asarray(art.get_qvel(), dtype=float)
    if not (np.isfinite(q).all() and np.isfinite(qd).all()):
        finite_ok = False
        finite_where.append("rest")
    for i, n in enumerate(names):
        js = spec_of[n]
        lin = js.type == "prismatic"
        lim = tol.drift_linear if lin else tol.drift_angular
        vlim = tol.max_linear_velocity if lin else tol.max_angular_velocity
        ok = bool(np.isfinite(maxdev[i]) and maxdev[i] <= lim and abs(qd[i]) <= vlim)
        checks.append(
            Check(
                "rest_drift",
                "dynamic",
                n,
                ok,
                value={"drift": maxdev[i], "speed": abs(qd[i])},
                tolerance={"drift": lim, "speed": vlim},
                message=""
                if ok
                else f"drifts {maxdev[i]:.4f} {'m' if lin else 'rad'} in "
                f"{tol.settle_time:g} s under gravity (speed {abs(qd[i]):.3f})",
                details={
                    "gravity_force": float(tau[i]),
                    "mass": masses[n],
                    "damping": js.damping,
                    "friction": js.friction,
                    "duration": tol.settle_time,
                },
            )
        )
    # --- PD drive, one joint at a time, the others held closed
    art.set_qpos(lower.astype(np.float32))
    art.set_qvel(np.zeros(len(names), dtype=np.float32))
    w = 2 * math.pi * tol.drive_frequency
    gains = {}
    for n in names:
        js = spec_of[n]
        m = _effective_inertia(art, joints[n], js.type)
        # PhysX joint friction resists in proportion to the joint's load (about the
        # part's weight): stiffen the drive so that it beats that within the error band
        weight = float(joints[n].child_link.mass) * 9.81
        band = 0.5 * tol.drive_error * (js.upper - js.lower)
        k = m * w * w + js.friction * weight / band
        c = 2 * math.sqrt(k * m) + js.damping
        limit = js.effort if js.effort > 0 else 3.4e38
        gains[n] = (k, c, limit)
        joints[n].set_drive_properties(k, c, limit, "force")
        joints[n].set_drive_target(float(js.lower))
    steps = round(tol.drive_time / dt)
    for i, n in enumerate(names):
        js = spec_of[n]
        rng = js.upper - js.lower
        target = js.lower + tol.drive_fraction * rng
        times: list[float | None] = []
        reached_q = []
        for goal in (target, js.lower):
            joints[n].set_drive_target(float(goal))
            t_hit = None
            for s in range(steps):
                # gravity compensation, as a robot's PD controller balances passive forces
                art.set_qf(art.compute_passive_force(True, True))
                scene.step()
                qi = float(art.get_qpos()[i])
                if not math.isfinite(qi):
                    finite_ok = False
                    finite_where.append(f"drive {n}")
                    break
                if abs(qi - goal) <= tol.drive_error * rng:
                    t_hit = (s + 1) * dt
                    break
            times.append(t_hit)
            reached_q.append(float(art.get_qpos()[i]))
        ok = all(t is not None for t in times)
        checks.append(
            Check(
                "drive_reach",
                "dynamic",
                n,
                ok,
                value={"open_s": times[0], "close_s": times[1]},
                tolerance={"time_s": tol.drive_time, "error": tol.drive_error * rng},
                message=""
                if ok
                else f"PD drive jammed: reached q={reached_q} toward "
                f"[{target:.3f}, {js.lower:.3f}] within {tol.drive_time:g} s",
                details={"gains": gains[n], "q": reached_q},
            )
        )
    # --- free base on the floor
    checks.append(_free_base_check(spec, tol, options))
    checks.append(
        Check(
            "finite",
            "dynamic",
            "asset",
            finite_ok,
            value=finite_where or None,
            tolerance="no NaN/inf",
            message="" if finite_ok else f"non-finite state in {finite_where}",
        )
    )
    return checks


def _free_base_check(spec: UrdfSpec, tol: Tolerances, options: SimOptions) -> Check:
    import sapien

    scene = physics_scene(options)
    scene.add_ground(
        0.0,
        render=False,
        material=sapien.physx.PhysxMaterial(
            options.static_friction, options.dynamic_friction, options.restitution
        ),
    )
    art = load_physics(scene, spec.path, options, fix_root=False)
    art.set_sleep_threshold(0.0)
    start = np.array([0.0, 0.0, 0.002])
    art.set_root_pose(sapien.Pose(start))
    names = [j.name for j in art.get_active_joints()]
    spec_of = {j.name: j for j in spec.movable_joints}
    art.set_qpos(np.array([spec_of[n].lower for n in names], dtype=np.float32))
    for _ in range(round(tol.free_time / options.timestep)):
        scene.step()
    T = np.asarray(art.get_root_pose().to_transformation_matrix())
    if not np.isfinite(T).all():
        return Check(
            "free_base_stable",
            "dynamic",
            "asset",
            False,
            value=None,
            message="non-finite base pose",
        )
    tilt = float(math.acos(float(np.clip(T[2, 2], -1, 1))))
    disp = float(np.linalg.norm(T[:3, 3] - start))
    v = float(np.linalg.norm(art.get_root_linear_velocity()))
    wv = float(np.linalg.norm(art.get_root_angular_velocity()))
    ok = (
        tilt <= tol.free_tilt
        and disp <= tol.free_displacement
        and v <= tol.max_linear_velocity
        and wv <= tol.max_angular_velocity
    )
    return Check(
        "free_base_stable",
        "dynamic",
        "asset",
        ok,
        value={"tilt": tilt, "displacement": disp, "speed": v, "angular_speed": wv},
        tolerance={
            "tilt": tol.free_tilt,
            "displacement": tol.free_displacement,
            "speed": tol.max_linear_velocity,
            "angular_speed": tol.max_angular_velocity,
        },
        message=""
        if ok
        else f"free on the floor the base tilts {math.degrees(tilt):.1f} deg "
        f"and moves {disp * 1000:.0f} mm",
    )


# --------------------------------------------------------------------------- running


def check_asset(
    asset_dir: str | Path,
    tol: Tolerances = DEFAULT_TOLERANCES,
    options: SimOptions = DEFAULT_SIM_OPTIONS,
    timings: dict[str, float] | None = None,
) -> list[Check]:
    """Run every stage once; a stage runs only when the stages it needs passed.

    ``timings`` (when given) accumulates seconds per stage.
    """
    timings = timings if timings is not None else {}
    urdf = Path(asset_dir) / URDF_NAME

    def timed(stage: str, fn: Callable[[], list[Check]]) -> list[Check]:
        t = time.perf_counter()
        try:
            return fn()
        finally:
            timings[stage] = timings.get(stage, 0.0) + time.perf_counter() - t

    t0 = time.perf_counter()
    try:
        spec = read_urdf(urdf)
        missing = [
            p.filename for lk in spec.links.values() for p in lk.pieces if not p.path.is_file()
        ]
    except AssetFormatError as e:
        timings["static"] = timings.get("static", 0.0) + time.perf_counter() - t0
        return [
            Check(
                "urdf", "static", "asset", False, value=str(e), tolerance="parses", message=str(e)
            )
        ]
    checks = [
        Check(
            "urdf",
            "static",
            "asset",
            not missing,
            value=missing or "parsed",
            tolerance="parses, files exist",
            message="" if not missing else f"missing collision files: {missing}",
        )
    ]
    timings["static"] = timings.get("static", 0.0) + time.perf_counter() - t0
    if missing:
        return checks
    checks += timed("static", lambda: static_checks(spec, tol))
    structural = {
        "single_root",
        "has_movable_part",
        "axis_unit",
        "limits_ordered",
        "mass_positive",
        "inertia_valid",
    }
    if any(not c.passed and c.name in structural for c in checks):
        return checks  # SAPIEN would reject or silently alter these: stop here
    checks += timed("load", lambda: load_checks(spec, tol, options))
    if any(not c.passed and c.name == "sapien_load" for c in checks):
        return checks
    checks += timed("kinematic", lambda: kinematic_checks(spec, tol))
    checks += timed("dynamic", lambda: dynamic_checks(spec, tol, options))
    return checks


def _asset_id(asset_dir: Path) -> str:
    meta = asset_dir / "asset.json"
    if meta.is_file():
        try:
            return str(json.loads(meta.read_text()).get("id", asset_dir.name))
        except (json.JSONDecodeError, OSError):
            pass
    return asset_dir.name


def validate_asset(
    asset_dir: str | Path,
    *,
    repair: bool = True,
    max_rounds: int = 3,
    preview: bool = True,
    tolerances: Tolerances = DEFAULT_TOLERANCES,
    options: SimOptions = DEFAULT_SIM_OPTIONS,
    write: bool = True,
) -> Report:
    """Check a built asset, repair what can be repaired, write ``report.json`` (+ preview).

    Each round runs every check; failed checks with a known repair are repaired
    (edits to ``model.urdf``, ``collision/*.obj``, ``asset.json``, ``model.xml``,
    each written atomically) and the next round re-checks everything, up to
    ``max_rounds`` rounds of repairs. Status: "ok" (passed without repairs),
    "repaired" (passed after repairs), "failed" (``reasons`` says why).
    """
    from .repair import plan_and_apply

    asset_dir = Path(asset_dir)
    timings: dict[str, float] = {}
    repairs: list[RepairRecord] = []
    rounds: list[dict[str, Any]] = []
    reasons: list[str] = []
    rnd = 0
    while True:
        checks = check_asset(asset_dir, tolerances, options, timings)
        failed = [c for c in checks if not c.passed]
        rounds.append({"round": rnd, "failed": [c.key for c in failed]})
        if not failed:
            break
        if not repair or rnd >= max_rounds:
            reasons = [f"{c.key}: {c.message or 'failed'}" for c in failed]
            if repair and rnd >= max_rounds:
                reasons.append(f"still failing after {max_rounds} rounds of repairs")
            break
        t = time.perf_counter()
        applied, unrepairable = plan_and_apply(asset_dir, checks, tolerances, round_=rnd + 1)
        timings["repair"] = timings.get("repair", 0.0) + time.perf_counter() - t
        repairs += applied
        if not applied:
            reasons = [f"{c.key}: {c.message or 'failed'}" for c in failed]
            reasons += [f"not repairable: {r}" for r in unrepairable]
            break
        rnd += 1
    failed = [c for c in checks if not c.passed]
    status = "failed" if failed else ("repaired" if repairs else "ok")
    report = Report(
        asset=_asset_id(asset_dir),
        status=status,
        checks=checks,
        repairs=repairs,
        rounds=rounds,
        reasons=reasons,
        timings=timings,
        tolerances=tolerances,
        sim_options=options,
    )
    if preview and write:
        from .preview import render_preview

        t = time.perf_counter()
        try:
            p = render_preview(asset_dir)
        except Exception as e:  # noqa: BLE001 - a preview must never fail validation
            log.warning("%s: preview failed: %s", asset_dir, e)
            p = None
        timings["preview"] = time.perf_counter() - t
        report.preview = p.name if p is not None else None
    if write:
        write_report(report, asset_dir)
    log.info("%s: %s (%d checks, %d repairs)", report.asset, status, len(checks), len(repairs))
    return report

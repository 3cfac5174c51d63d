"""The validation report: checks, repairs, tolerances, and ``report.json`` (its one
reader and writer).

A :class:`Report` holds every :class:`Check` (name, stage, subject, passed, measured
value, tolerance, message), every :class:`RepairRecord` and the outcome: ``ok``
(passed as built), ``repaired`` (passed after repairs) or ``failed`` (``reasons``
says why). Thresholds are the :class:`Tolerances`; docs/validation.md lists them.
"""

from __future__ import annotations

import json
import math
from dataclasses import asdict, dataclass, field, fields
from pathlib import Path
from typing import Any

import numpy as np

from asset_pipeline.simulation.sim_options import DEFAULT_SIM_OPTIONS, SimOptions
from generator.atomic_files import atomic_write_bytes

REPORT_SCHEMA = "pact.validation"
REPORT_VERSION = 1
REPORT_NAME = "report.json"
STAGES = ("static", "load", "kinematic", "dynamic")
#: The statuses a report can have: passed as built, passed after repairs, failed.
STATUSES = ("ok", "repaired", "failed")


class ReportFormatError(ValueError):
    """A ``report.json`` cannot be read; the message names the file and what is wrong."""


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
    #: ... or this fraction of the part's largest extent, if more (a real 1.2 m fridge
    #: door hangs on hinges set 3 cm into the cabinet).
    hinge_offset_relative: float = 0.05
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
    #: A touch opens a part this fraction of its range (at most 3 degrees or 1 cm) ...
    touch: float = 0.02
    touch_max_angular: float = math.radians(3.0)
    touch_max_linear: float = 0.01
    #: ... and a pull of this many newtons at its handle opens it at least this fraction
    #: of its range within this many seconds.
    pull_force: float = 40.0
    pull_fraction: float = 0.3
    pull_time: float = 2.0
    #: Engine parity (:mod:`.engines`): a part pulled or pushed against a joint limit
    #: passes it by at most this much (m, rad).
    limit_linear: float = 0.005
    limit_angular: float = math.radians(2.0)
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
    #: Likeness to the photo (asset_pipeline.photo.fidelity; docs/fidelity.md), None when not
    #: measured. Written by the convert's ``fidelity`` stage after validation.
    fidelity: dict[str, Any] | None = None
    #: The behaviour checks in other engines (``pact validate --engines``;
    #: :func:`asset_pipeline.validate.engines.engine_report`), None when not run.
    engines: dict[str, Any] | None = None

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
            "checks": [jsonable(asdict(c)) for c in self.checks],
            "repairs": [jsonable(asdict(r)) for r in self.repairs],
            "rounds": jsonable(self.rounds),
            "timings": {k: round(v, 4) for k, v in self.timings.items()},
            "preview": self.preview,
            "tolerances": jsonable(asdict(self.tolerances)),
            "sim_options": jsonable(asdict(self.sim_options)),
            "fidelity": None if self.fidelity is None else jsonable(self.fidelity),
            **({} if self.engines is None else {"engines": _engines_json(self.engines)}),
        }


def _engines_json(engines: dict[str, Any]) -> dict[str, Any]:
    out = {}
    for name, section in engines.items():
        if isinstance(section, dict) and "checks" in section:
            checks = [asdict(c) if isinstance(c, Check) else c for c in section["checks"]]
            section = {**section, "checks": checks}
        out[name] = jsonable(section)
    return out


def jsonable(x: Any) -> Any:
    if isinstance(x, dict):
        return {str(k): jsonable(v) for k, v in x.items()}
    if isinstance(x, (list, tuple)):
        return [jsonable(v) for v in x]
    if isinstance(x, np.ndarray):
        return jsonable(x.tolist())
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
    path = Path(asset_dir) / REPORT_NAME
    atomic_write_bytes(path, json.dumps(report.to_json(), indent=2).encode())
    return path


def _known(cls: type, d: Any) -> dict[str, Any]:
    names = {f.name for f in fields(cls)}
    return {k: v for k, v in d.items() if k in names} if isinstance(d, dict) else {}


def read_report(asset_dir: str | Path) -> Report | None:
    """The ``report.json`` of an asset folder as a :class:`Report`, None when there is none.

    Raises :class:`ReportFormatError` naming the file when it is not a readable
    report of schema ``pact.validation``.
    """
    path = Path(asset_dir) / REPORT_NAME
    if not path.is_file():
        return None
    try:
        doc = json.loads(path.read_text(encoding="utf-8"))
    except (OSError, json.JSONDecodeError, UnicodeDecodeError) as e:
        raise ReportFormatError(f"{path}: not valid JSON: {e}") from e
    if not isinstance(doc, dict) or doc.get("schema") != REPORT_SCHEMA:
        raise ReportFormatError(f"{path}: not a validation report (schema {REPORT_SCHEMA!r})")
    status = doc.get("status")
    if status not in STATUSES:
        raise ReportFormatError(f"{path}: status {status!r} is not one of {list(STATUSES)}")
    try:
        checks = [Check(**_known(Check, c)) for c in doc.get("checks", [])]
        repairs = [RepairRecord(**_known(RepairRecord, r)) for r in doc.get("repairs", [])]
    except TypeError as e:
        raise ReportFormatError(f"{path}: malformed check or repair: {e}") from e
    return Report(
        asset=str(doc.get("asset", Path(asset_dir).name)),
        status=status,
        checks=checks,
        repairs=repairs,
        rounds=list(doc.get("rounds", [])),
        reasons=[str(r) for r in doc.get("reasons", [])],
        timings=dict(doc.get("timings", {})),
        preview=doc.get("preview"),
        tolerances=Tolerances(**_known(Tolerances, doc.get("tolerances"))),
        sim_options=SimOptions(**_known(SimOptions, doc.get("sim_options"))),
        fidelity=doc["fidelity"] if isinstance(doc.get("fidelity"), dict) else None,
        engines=doc["engines"] if isinstance(doc.get("engines"), dict) else None,
    )

"""Prove a built asset in SAPIEN: static, load, kinematic and dynamic checks, repairs, report.

Stages and checks (check name, what it measures; thresholds in :class:`Tolerances`,
documented in docs/validation.md):

static (the files and the model, no simulator; :mod:`.static`)
    ``urdf``                  the URDF reads (XML, a <robot>, every number finite, every mesh
                              path inside the asset folder) and every referenced file exists
    ``asset_json``            asset.json, when present, reads
    ``single_root``, ``has_movable_part``, ``axis_unit``, ``limits_ordered``,
    ``mass_positive``, ``inertia_valid``, ``collision_hulls``, ``hinge_on_part``
    ``usd_stage``, ``usd_matches_urdf`` (when the folder holds ``model.usdc``: USD's own
                              validators and physics parser; :mod:`.usd_checks`)
load (SAPIEN on CPU; :mod:`.load`)
    ``sapien_load``, ``collision_shapes``, ``joint_matches_urdf``
kinematic (PhysX contact generation between per-link probe bodies; :mod:`.kinematic`)
    ``rest_penetration``, ``open_penetration``, ``sweep_penetration``, ``drawer_engaged``,
    ``opens_outward``
dynamic (PhysX CPU with the tasks' SimOptions; :mod:`.dynamic`)
    ``rest_drift``, ``finite``, ``drive_reach``, ``free_base_stable``

:func:`validate_asset` (:mod:`.runner`) runs them, repairs (:mod:`.repair`), re-checks
and writes ``report.json`` (:mod:`.report`, its one reader and writer). With ``engines``
it also runs the behaviour checks of :mod:`.engines` in SAPIEN, MuJoCo (the MJCF,
:mod:`.engine_mujoco`) and Newton (the USD, :mod:`.engine_newton`): ``report.engines``.
"""

from asset_pipeline.validate.report import (
    DEFAULT_TOLERANCES,
    REPORT_NAME,
    STAGES,
    STATUSES,
    Check,
    RepairRecord,
    Report,
    ReportFormatError,
    Tolerances,
    read_report,
    write_report,
)
from asset_pipeline.validate.runner import check_asset, validate_asset

__all__ = [
    "DEFAULT_TOLERANCES",
    "REPORT_NAME",
    "STAGES",
    "STATUSES",
    "Check",
    "RepairRecord",
    "Report",
    "ReportFormatError",
    "Tolerances",
    "check_asset",
    "read_report",
    "validate_asset",
    "write_report",
]

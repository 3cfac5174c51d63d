"""Numbers and poses as the text of XML attributes (URDF, MJCF): deterministic and short."""

from __future__ import annotations

from typing import Any

import numpy as np
import trimesh


def fmt(x: float) -> str:
    """Deterministic short float text (10 significant digits, no negative zero)."""
    return f"{float(x) + 0.0:.10g}"


def vec(v: Any) -> str:
    return " ".join(fmt(x) for x in np.asarray(v, dtype=float).ravel())


def rounded(v: Any) -> list[float]:
    return [round(float(x) + 0.0, 9) for x in np.asarray(v, dtype=float).ravel()]


def is_identity(T: np.ndarray) -> bool:
    return bool(np.allclose(T, np.eye(4), rtol=0.0, atol=1e-12))


def xyz_rpy(T: np.ndarray) -> tuple[str, str]:
    """URDF ``xyz`` and ``rpy`` (fixed-axis roll, pitch, yaw) text of a rigid (4, 4)."""
    if np.allclose(T[:3, :3], np.eye(3), rtol=0.0, atol=1e-12):
        rpy = np.zeros(3)
    else:
        rpy = np.array(trimesh.transformations.euler_from_matrix(T, axes="sxyz"))
    return vec(T[:3, 3]), vec(rpy)


def quat_wxyz(T: np.ndarray) -> np.ndarray:
    return np.asarray(trimesh.transformations.quaternion_from_matrix(T), dtype=float)

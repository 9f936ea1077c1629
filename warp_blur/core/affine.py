"""Inverting USD's affine transforms (row vectors: p' = p M, rows 0-2 the linear part, row 3 the
translation) robustly: a camera or prim far from the origin (a translation of 1e30 beside a unit
rotation) defeats a general 4×4 LU inverse, which then reports the matrix singular."""

from __future__ import annotations

import numpy as np

from .errors import StageError


def invert_affine(m: np.ndarray) -> np.ndarray:
    """(4, 4) float64 inverse of an affine row-vector matrix: np.linalg.inv where it succeeds with a
    finite result that inverts m (every ordinary transform, unchanged), else the affine form (the
    linear part inverted, the translation -t L⁻¹). Raises np.linalg.LinAlgError when the linear
    part itself is singular (a zero scale)."""
    m = np.asarray(m, np.float64)
    try:
        with np.errstate(all="ignore"):
            inv = np.linalg.inv(m)
            # LU on rows whose scales differ by many orders can also 'succeed' with a wrong result
            good = np.isfinite(inv).all() and np.abs(m @ inv - np.eye(4)).max() <= 1e-6
        if good:
            return inv
    except np.linalg.LinAlgError:
        pass
    lin_inv = np.linalg.inv(m[:3, :3])
    out = np.zeros((4, 4), np.float64)
    out[:3, :3] = lin_inv
    with np.errstate(all="ignore"):
        out[3, :3] = -m[3, :3] @ lin_inv
    out[3, 3] = 1.0
    if not np.isfinite(out).all():
        raise np.linalg.LinAlgError("the transform's inverse is not finite")
    return out


def camera_from_world(cam_to_world: np.ndarray, camera: str, time: float) -> np.ndarray:
    """invert_affine of a camera's local-to-world matrix; a StageError naming the camera where it
    has no inverse (a zero scale, or values beyond float64)."""
    try:
        return invert_affine(cam_to_world)
    except np.linalg.LinAlgError:
        raise StageError(f"the camera {camera} has a transform at time {time:g} that cannot be inverted "
                         f"(a zero scale, or values beyond float64)") from None

"""UsdGeom.Points as camera-facing discs, tessellated so that every method renders them as
triangles: each point is an equal-area octagon of its `widths` (diameter, in the prim's local
units) in the plane facing the camera at the frame time, centred on the point as USD places it at
each shutter time (time samples, or `velocities` through ComputePointsAtTime). The disc's plane
is fixed for the frame, so a point's blur is its centre's motion (a spark's streak)."""

from __future__ import annotations

from typing import Callable

import numpy as np
from pxr import Usd, UsdGeom

from ..core.affine import invert_affine
from .values import array_value, value_count


#: sides of the polygon standing for a disc, and the radius scale that gives it the disc's area
DISC_SIDES = 8
DISC_RADIUS_SCALE = float(np.sqrt(np.pi / (0.5 * DISC_SIDES * np.sin(2.0 * np.pi / DISC_SIDES))))
DEFAULT_WIDTH = 1.0


def disc_triangles(num_points: int) -> np.ndarray:
    """(num_points * DISC_SIDES, 3) int32 fan triangles over vertices laid out per point as
    [centre, rim_0 .. rim_{S-1}] (counter-clockwise seen from the camera)."""
    per = DISC_SIDES + 1
    base = np.arange(num_points, dtype=np.int64)[:, None] * per
    k = np.arange(DISC_SIDES)
    tris = np.stack([np.zeros(DISC_SIDES, np.int64), 1 + k, 1 + (k + 1) % DISC_SIDES], axis=1)
    return (base[:, None, :] + tris[None]).reshape(-1, 3).astype(np.int32)


def disc_vertices(centres: np.ndarray, radii: np.ndarray, right: np.ndarray, up: np.ndarray) -> np.ndarray:
    """(N * (DISC_SIDES + 1), 3) float64 disc vertices of centres (N, 3) with radii (N,), in the
    plane spanned by the unit vectors right and up (3,)."""
    angles = 2.0 * np.pi * np.arange(DISC_SIDES) / DISC_SIDES
    ring = np.cos(angles)[:, None] * right[None] + np.sin(angles)[:, None] * up[None]     # (S, 3)
    rim = centres[:, None, :] + (radii * DISC_RADIUS_SCALE)[:, None, None] * ring[None]          # (N, S, 3)
    return np.concatenate([centres[:, None, :], rim], axis=1).reshape(-1, 3)


def point_radii(points: UsdGeom.Points, time: Usd.TimeCode, count: int) -> np.ndarray | None:
    """(count,) radii from `widths` (per point, or one for all; USD's default of 1 unauthored),
    or None when the widths do not fit the points or are not finite positive numbers."""
    w = array_value(points.GetWidthsAttr(), time, np.float64).reshape(-1)
    if len(w) == 0:
        return np.full(count, DEFAULT_WIDTH / 2.0)
    if len(w) == 1:
        w = np.full(count, w[0])
    if len(w) != count or not (np.isfinite(w).all() and (w >= 0).all()):
        return None
    return w / 2.0


def facing_axes(prim: Usd.Prim, camera_prim: Usd.Prim, cache: UsdGeom.XformCache) -> tuple[np.ndarray, np.ndarray]:
    """(right, up) unit vectors in the prim's local space of the camera's image plane at the
    cache's time (a disc in their span faces the camera)."""
    cam_w = np.array(cache.GetLocalToWorldTransform(camera_prim), np.float64)
    prim_w = np.array(cache.GetLocalToWorldTransform(prim), np.float64)
    try:
        with np.errstate(all="ignore"):
            cam_in_prim = cam_w @ invert_affine(prim_w)      # row vectors: camera local -> prim local
    except np.linalg.LinAlgError:   # a zero scale: the points collapse, any axes do
        cam_in_prim = np.eye(4)
    axes = []
    for row in (0, 1):
        v = cam_in_prim[row, :3]
        n = np.linalg.norm(v)
        axes.append(v / n if np.isfinite(n) and n > 0 else np.eye(3)[row])
    return axes[0], axes[1]


def derived_points_fn(source_at: Callable[[float], np.ndarray],
                      derive: Callable[[np.ndarray], np.ndarray]) -> Callable[[float], np.ndarray]:
    """time -> derive(source_at(time)), derived again only when the source gives another array
    (a still prim's points function returns one cached array: its discs, ribbons or refined
    surface are then made once, not at every shutter instant)."""
    last: dict = {}

    def points_at(time: float) -> np.ndarray:
        source = source_at(time)
        if last.get("source") is not source:
            last["source"], last["points"] = source, derive(source)
        return last["points"]
    points_at.held = getattr(source_at, "held", False)   # a held source: one derived array too
    return points_at


def points_unit_fields(scene, prim: Usd.Prim, t: Usd.TimeCode) -> dict | None:
    """GeomUnit fields of a UsdGeom.Points prim as camera-facing discs (None: nothing to render, or
    dropped as invalid); `scene` is the usd.scene.Scene being built (it makes them double-sided)."""
    schema = UsdGeom.Points(prim)
    path = str(prim.GetPath())
    n = value_count(schema.GetPointsAttr(), t)
    if n == 0:
        return None
    radii = point_radii(schema, t, n)
    if radii is None and scene._invalid(path, "widths do not match the points or are not finite non-negative numbers"):
        return None
    centres_at = scene._valid_points_fn(prim, n)
    if centres_at is None:
        return None
    right, up = facing_axes(prim, scene.camera.GetPrim(), scene._xf_cache(scene.frame))
    point_of_tri = np.repeat(np.arange(n), DISC_SIDES)
    material, flags, blur = scene._common(prim, t)
    colors, uvs, opacity = scene._surface_primvars(prim, t, material, np.repeat(point_of_tri[:, None], 3, axis=1),
                                         point_of_tri, None)
    return dict(
        path=path, prim=prim, local_tris=disc_triangles(n), num_points=n * (DISC_SIDES + 1),
        points_at=derived_points_fn(centres_at, lambda c: disc_vertices(c, radii, right, up)), transforms_at=scene._prim_transform_fn(prim),
        num_instances=1, corner_colors=colors, corner_uvs=uvs, corner_opacity=opacity, material=material,
        flags=flags, blur_scale=blur, visibility_prims=[prim])

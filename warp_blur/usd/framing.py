"""A camera that frames the stage when the stage has none (as usdrecord and usdview do).

The camera lives in the stage's session layer (the file on disk is never touched) at
FRAMING_CAMERA_PATH, so the rest of the pipeline reads it like any authored UsdGeom.Camera.
Placement follows UsdAppUtils' frame recorder: USD's fallback 50 mm lens, looking along -Z
(Y-up stages) or +Y (Z-up stages, rotated 90° about X) at the centre of the world bounds of the
render and default purposes at the frame time, backed off so the bounds' half diagonal in the
focal plane fills the narrower field of view, then past the front face of the bounds. The
clipping range holds the whole bounding sphere. It is placed again for every frame rendered
(held still over each shutter, so it adds no camera motion).
"""

from __future__ import annotations

import math

import numpy as np
from pxr import Gf, Sdf, Usd, UsdGeom

from ..core.errors import StageError
from ..core.log import warn_once

FRAMING_CAMERA_PATH = "/WarpBlurFramingCamera"
_FOCAL_LENGTH = 50.0
_H_APERTURE = 20.955      # USD's fallback apertures (mm, tenths of a scene unit by convention)
_V_APERTURE = 15.2908


def stage_bounds(stage: Usd.Stage, frame: float) -> Gf.Range3d | None:
    """World-space axis-aligned bounds of the render and default purposes at `frame` (None: empty
    or not finite)."""
    purposes = [UsdGeom.Tokens.default_, UsdGeom.Tokens.render]
    time = frame if isinstance(frame, Usd.TimeCode) else Usd.TimeCode(frame)
    cache = UsdGeom.BBoxCache(time, purposes, useExtentsHint=False)
    box = cache.ComputeWorldBound(stage.GetPseudoRoot()).ComputeAlignedRange()
    if box.IsEmpty() or not all(math.isfinite(v) and abs(v) < 1e30 for v in (*box.GetMin(), *box.GetMax())):
        return None
    return box


def framing_pose(bounds: Gf.Range3d, up_axis: str, aspect: float) -> tuple[np.ndarray, float, float]:
    """(4, 4) float64 camera-to-world matrix (row vectors), near and far clipping distances that
    frame `bounds` with the 50 mm lens at image aspect `aspect` (width / height)."""
    centre = np.array(bounds.GetMidpoint(), np.float64)
    size = np.array(bounds.GetSize(), np.float64)
    z_up = up_axis == UsdGeom.Tokens.z
    plane = np.array([size[0], size[2]] if z_up else [size[0], size[1]]) / 2.0
    depth = size[1] if z_up else size[2]
    v_aperture = max(_V_APERTURE, _H_APERTURE / aspect)        # expandAperture conform
    h_aperture = max(_H_APERTURE, _V_APERTURE * aspect)
    half_fov = math.atan(min(h_aperture, v_aperture) / (2.0 * _FOCAL_LENGTH))
    radius_in_plane = float(np.hypot(*plane))
    distance = max(radius_in_plane / math.tan(half_fov) + depth / 2.0, 1e-3)
    xf = np.eye(4)
    if z_up:   # camera -Z looks along world +Y, camera +Y is world +Z
        xf[:3, :3] = [[1, 0, 0], [0, 0, 1], [0, -1, 0]]
        xf[3, :3] = centre + [0.0, -distance, 0.0]
    else:
        xf[3, :3] = centre + [0.0, 0.0, distance]
    radius = max(float(np.linalg.norm(size)) / 2.0, 1e-6)
    near = max(distance - radius, radius * 1e-3) * 0.9
    far = (distance + radius) * 1.1
    return xf, near, far


def has_geometry(stage: Usd.Stage) -> bool:
    """True when the stage holds a gprim or a point instancer (renderable or not)."""
    return any(p.IsA(UsdGeom.Gprim) or p.IsA(UsdGeom.PointInstancer) for p in stage.Traverse())


def define_framing_camera(stage: Usd.Stage) -> UsdGeom.Camera:
    """The framing camera prim (created once in the session layer; placed by place_framing_camera)."""
    prim = stage.GetPrimAtPath(FRAMING_CAMERA_PATH)
    if prim and prim.IsA(UsdGeom.Camera):
        return UsdGeom.Camera(prim)
    if stage_bounds(stage, stage.GetStartTimeCode()) is None and stage_bounds(stage, Usd.TimeCode.Default()) is None \
            and not has_geometry(stage):
        # geometry without finite bounds (e.g. an instancer whose indices are out of range) is framed
        # as a unit box, so that loading it reports what is wrong with it
        raise StageError("the stage has no camera and no geometry to frame (add a UsdGeom.Camera or pass --camera)")
    with Usd.EditContext(stage, stage.GetSessionLayer()):
        cam = UsdGeom.Camera.Define(stage, Sdf.Path(FRAMING_CAMERA_PATH))
        cam.CreateFocalLengthAttr(_FOCAL_LENGTH)
        cam.CreateHorizontalApertureAttr(_H_APERTURE)
        cam.CreateVerticalApertureAttr(_V_APERTURE)
        cam.MakeMatrixXform()
    # once per stage within a scope (core/log.py: a Renderer's); keyed by the prim path alone, only
    # the first camera-less stage of a scope would be told
    warn_once(f"framing-camera:{stage.GetRootLayer().identifier}",
              "the stage has no camera: rendering through a computed camera that frames its bounds (pass "
              "--camera to choose one)")
    return cam


def place_framing_camera(stage: Usd.Stage, camera: UsdGeom.Camera, frame: float, aspect: float) -> None:
    """Point the framing camera at the stage's bounds at `frame` (a default value: still over the shutter)."""
    bounds = stage_bounds(stage, frame) or Gf.Range3d(Gf.Vec3d(-1, -1, -1), Gf.Vec3d(1, 1, 1))
    xf, near, far = framing_pose(bounds, UsdGeom.GetStageUpAxis(stage), aspect)
    with Usd.EditContext(stage, stage.GetSessionLayer()):
        op = UsdGeom.Xformable(camera).MakeMatrixXform()
        op.Set(Gf.Matrix4d(xf.tolist()))
        camera.GetClippingRangeAttr().Set(Gf.Vec2f(float(near), float(far)))


def is_framing_camera(camera: UsdGeom.Camera) -> bool:
    return str(camera.GetPath()) == FRAMING_CAMERA_PATH

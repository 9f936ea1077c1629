"""UsdLux lights into per-instant tables in camera space (SPEC §4).

Radiance of a light is color × intensity × 2^exposure (÷ world-space area with inputs:normalize).
Table columns (LIGHT_WIDTH floats per light), read by `shading.py`:
  0 type (0 distant, 1 sphere/point, 2 rect, 3 disk), 1-3 radiance rgb, 4-6 position,
  7-9 emission axis (unit; for distant lights the direction *towards* the light),
  10-12 half-extent u axis, 13-15 half-extent v axis (for distant and sphere lights: the light's
  unit local x and y axes, which shadow maps use as the light's frame), 16 radius, 17 casts shadows
  (UsdLux `inputs:shadow:enable`, whose fallback is true).
Irradiance models: distant E = L π sin²(angle/2) cosθ (UsdLux: a disc of angular diameter
`inputs:angle`; E = L cosθ with inputs:normalize or angle 0), shadows hard whatever the angle; sphere of radius r at distance d: E = π L (r/d)² cosθ
(a point light, radius 0, has the intensity of USD's fallback 0.5 radius); rect and disk lights
are integrated over a fixed 4×4 stratified set of points on the light.
A DomeLight without texture is the background radiance and a uniform ambient term (with a
latlong texture: see dome.py).
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np
from pxr import Gf, Usd, UsdGeom, UsdLux

from ..core.log import warn_once
from .stage import visibility_varies

LIGHT_WIDTH = 18
DISTANT, SPHERE, RECT, DISK = 0, 1, 2, 3
POINT_LIGHT_RADIUS = 0.5


@dataclass
class LightPrim:
    prim: Usd.Prim
    kind: int
    held: dict = field(default_factory=dict)   # light_inputs' answer when no input can change in time


def _finite_input(light: UsdLux.LightAPI, attr, time: Usd.TimeCode, fallback, width: int) -> np.ndarray:
    """An authored light input as floats (width,), or USD's fallback with a warning (once per
    prim and input) when it is not finite or not a number: a NaN must never reach a pixel."""
    value = attr.Get(time)
    if value is None:
        return np.asarray(fallback, np.float64).reshape(width)
    try:
        arr = np.asarray(value, np.float64).reshape(width)
    except (TypeError, ValueError):
        arr = None
    if arr is None or not np.isfinite(arr).all() or np.abs(arr).max(initial=0.0) > 1e30:
        warn_once(f"light-input:{light.GetPath()}:{attr.GetName()}",
                  f"light {light.GetPath()}: {attr.GetName()} = {value} is not a finite number; "
                  f"using USD's fallback {fallback}")
        return np.asarray(fallback, np.float64).reshape(width)
    return arr


def distant_illuminance_factor(light: UsdLux.DistantLight, normalize: bool, time: Usd.TimeCode) -> float:
    """Illuminance at normal incidence per unit of a distant light's radiance (UsdLux): the
    light is a disc of angular diameter `inputs:angle`, so E = L π sin²(angle / 2); with
    inputs:normalize (or an angle of 0, a delta light) the intensity is the illuminance, E = L."""
    angle = float(_finite_input(light.LightAPI(), light.GetAngleAttr(), time, 0.53, 1)[0])
    if normalize or angle <= 0.0:
        return 1.0
    half = np.radians(min(angle, 360.0)) / 2.0
    return float(np.pi * np.sin(min(half, np.pi / 2)) ** 2)


def _radiance(light: UsdLux.LightAPI, time: Usd.TimeCode) -> np.ndarray:
    color = _finite_input(light, light.GetColorAttr(), time, (1.0, 1.0, 1.0), 3)
    intensity = float(_finite_input(light, light.GetIntensityAttr(), time, 1.0, 1)[0])
    exposure = float(_finite_input(light, light.GetExposureAttr(), time, 0.0, 1)[0])
    return color * intensity * 2.0 ** min(exposure, 100.0)


def find_lights(stage: Usd.Stage) -> tuple[list[LightPrim], np.ndarray | None]:
    """Supported lights in traversal order, and the dome radiance (None without a dome)."""
    lights: list[LightPrim] = []
    dome = None
    for prim in stage.Traverse(Usd.TraverseInstanceProxies(Usd.PrimDefaultPredicate)):
        if not prim.HasAPI(UsdLux.LightAPI):
            continue
        path = str(prim.GetPath())
        if prim.IsA(UsdLux.DistantLight):
            lights.append(LightPrim(prim, DISTANT))
        elif prim.IsA(UsdLux.SphereLight):
            lights.append(LightPrim(prim, SPHERE))
        elif prim.IsA(UsdLux.RectLight):
            if UsdLux.RectLight(prim).GetTextureFileAttr().Get():
                warn_once(f"tex:{path}", f"light {path}: textureFile is not supported (uniform colour used)")
            lights.append(LightPrim(prim, RECT))
        elif prim.IsA(UsdLux.DiskLight):
            lights.append(LightPrim(prim, DISK))
        elif prim.IsA(UsdLux.DomeLight) or prim.IsA(UsdLux.DomeLight_1):
            if dome is not None:
                warn_once(f"dome2:{path}", f"dome light {path} ignored: only the first dome light is used")
                continue
            dome = LightPrim(prim, -1)
        else:
            warn_once(f"light:{path}", f"light {path} ({prim.GetTypeName()}) is not supported and is ignored")
    return lights, dome


def dome_radiance(dome: LightPrim | None, frame: float) -> np.ndarray:
    """Background/ambient radiance rgb (zeros without a dome, or when it is invisible)."""
    if dome is None:
        return np.zeros(3, np.float32)
    t = Usd.TimeCode(frame)
    if UsdGeom.Imageable(dome.prim).ComputeVisibility(t) == UsdGeom.Tokens.invisible:
        return np.zeros(3, np.float32)
    return _radiance(UsdLux.LightAPI(dome.prim), t).astype(np.float32)


def _input_attrs(lp: LightPrim) -> list[Usd.Attribute]:
    """The attributes light_inputs reads for the light's kind."""
    api = UsdLux.LightAPI(lp.prim)
    attrs = [api.GetColorAttr(), api.GetIntensityAttr(), api.GetExposureAttr(), api.GetNormalizeAttr(),
             UsdLux.ShadowAPI(lp.prim).GetShadowEnableAttr()]
    if lp.kind == DISTANT:
        attrs.append(UsdLux.DistantLight(lp.prim).GetAngleAttr())
    elif lp.kind == SPHERE:
        attrs += [UsdLux.SphereLight(lp.prim).GetRadiusAttr(), UsdLux.SphereLight(lp.prim).GetTreatAsPointAttr()]
    elif lp.kind == RECT:
        attrs += [UsdLux.RectLight(lp.prim).GetWidthAttr(), UsdLux.RectLight(lp.prim).GetHeightAttr()]
    elif lp.kind == DISK:
        attrs.append(UsdLux.DiskLight(lp.prim).GetRadiusAttr())
    return attrs


def light_inputs(lp: LightPrim, t: Usd.TimeCode) -> tuple:
    """(visible, radiance (3,), normalize, shadow, size) of a light at time t from its authored
    inputs: radiance with a distant light's illuminance factor in, size (radius, treated as a
    point) for a sphere, (width, height) for a rect, the radius of a disk, else 0. Read once a
    scene when none of the inputs, nor the light's visibility, has time samples (a frame's motion
    planning asks at every snapshot)."""
    if "inputs" in lp.held:
        return lp.held["inputs"]
    visible = UsdGeom.Imageable(lp.prim).ComputeVisibility(t) != UsdGeom.Tokens.invisible
    api = UsdLux.LightAPI(lp.prim)
    radiance = _radiance(api, t)
    normalize = bool(api.GetNormalizeAttr().Get(t))
    shadow = UsdLux.ShadowAPI(lp.prim).GetShadowEnableAttr().Get(t)
    size = 0.0
    if lp.kind == DISTANT:
        radiance = radiance * distant_illuminance_factor(UsdLux.DistantLight(lp.prim), normalize, t)
    elif lp.kind == SPHERE:
        sl = UsdLux.SphereLight(lp.prim)
        size = (float(_finite_input(api, sl.GetRadiusAttr(), t, 0.5, 1)[0]), bool(sl.GetTreatAsPointAttr().Get(t)))
    elif lp.kind == RECT:
        rl = UsdLux.RectLight(lp.prim)
        size = (float(_finite_input(api, rl.GetWidthAttr(), t, 1.0, 1)[0]),
                float(_finite_input(api, rl.GetHeightAttr(), t, 1.0, 1)[0]))
    elif lp.kind == DISK:
        size = float(_finite_input(api, UsdLux.DiskLight(lp.prim).GetRadiusAttr(), t, 0.5, 1)[0])
    inputs = (visible, radiance, normalize, shadow, size)
    if "varies" not in lp.held:
        lp.held["varies"] = visibility_varies([lp.prim]) or any(a and a.ValueMightBeTimeVarying()
                                                                for a in _input_attrs(lp))
    if not lp.held["varies"]:
        lp.held["inputs"] = inputs
    return inputs


def light_table(lights: list[LightPrim], time: float, cam_from_world: np.ndarray,
                xform_cache: UsdGeom.XformCache) -> np.ndarray:
    """(NL, LIGHT_WIDTH) float32 table of the lights at `time`, in camera space.

    cam_from_world: (4, 4) float64 row-vector matrix (p_cam = p_world @ M).
    """
    t = Usd.TimeCode(time)
    rows = []
    for lp in lights:
        # an invisible light keeps its row with no radiance: tables keep one row per light at every
        # instant, so animated visibility blends like any other light change
        visible, radiance, normalize, shadow, size = light_inputs(lp, t)
        m_world = np.array(xform_cache.GetLocalToWorldTransform(lp.prim), np.float64)
        # a light whose inputs hold still, seen from where it was last: the row made then
        key = m_world.tobytes() + cam_from_world.tobytes()
        memo = lp.held.get("row")
        if not lp.held["varies"] and memo is not None and memo[0] == key:
            rows.append(memo[1])
            continue
        m = m_world @ cam_from_world
        origin = m[3, :3]
        ax, ay, az = m[0, :3], m[1, :3], m[2, :3]
        row = np.zeros(LIGHT_WIDTH, np.float64)
        row[0] = lp.kind
        row[4:7] = origin
        row[17] = 1.0 if (shadow is None or shadow) else 0.0
        if lp.kind in (DISTANT, SPHERE):
            row[10:13] = ax / max(np.linalg.norm(ax), 1e-30)
            row[13:16] = ay / max(np.linalg.norm(ay), 1e-30)
        if lp.kind == DISTANT:
            row[7:10] = az / max(np.linalg.norm(az), 1e-30)
        elif lp.kind == SPHERE:
            with np.errstate(all="ignore"):
                scale = float(np.cbrt(abs(np.linalg.det(m_world[:3, :3]))))
            radius = size[0] * scale
            if size[1]:
                radius = 0.0
            row[16] = radius
            if normalize and radius > 0:
                radiance = radiance / (4.0 * np.pi * radius * radius)
        else:
            n = -az / max(np.linalg.norm(az), 1e-30)
            row[7:10] = n
            if lp.kind == RECT:
                hu = ax * size[0] / 2
                hv = ay * size[1] / 2
                area = 4.0 * np.linalg.norm(np.cross(hu, hv))
            else:
                hu, hv = ax * size, ay * size
                area = np.pi * np.linalg.norm(np.cross(hu, hv))
            row[10:13], row[13:16] = hu, hv
            if normalize and area > 0:
                radiance = radiance / area
        row[1:4] = radiance if visible else 0.0
        if not (np.isfinite(row).all() and np.abs(row).max() < 1e15):
            # a non-finite transform or size (a damaged stage): the light is dark and casts nothing
            warn_once(f"light-transform:{lp.prim.GetPath()}",
                      f"light {lp.prim.GetPath()}: its transform or size at time {time:g} is not finite; "
                      f"the light is ignored where it is")
            row = np.zeros(LIGHT_WIDTH, np.float64)
            row[0] = lp.kind
        lp.held["row"] = (key, row)
        rows.append(row)
    if not rows:
        return np.zeros((0, LIGHT_WIDTH), np.float32)
    return np.stack(rows).astype(np.float32)


def headlight_table() -> np.ndarray:
    """A distant light at the camera (towards +Z in camera space) with irradiance π: a white
    Lambert surface facing the camera shows its albedo (as usdview's headlight does)."""
    row = np.zeros((1, LIGHT_WIDTH), np.float32)
    row[0, 0] = DISTANT
    row[0, 1:4] = np.pi
    row[0, 7:10] = (0.0, 0.0, 1.0)
    return row


def gf_to_np(m: Gf.Matrix4d) -> np.ndarray:
    return np.array(m, np.float64)

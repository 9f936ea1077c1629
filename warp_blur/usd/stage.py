"""Opening stages and resolving what a render needs from them: camera, resolution, shutter, frames.

Precedence (SPEC §3): explicit argument > UsdRenderSettings > stage default.
"""

from __future__ import annotations

import math
import os
import re
from dataclasses import dataclass

from pxr import Gf, Sdf, Tf, Usd, UsdGeom, UsdRender, UsdUtils

from ..core.camera import Projection, conform_window
from ..core.errors import StageError, UserError
from .framing import FRAMING_CAMERA_PATH, define_framing_camera
from ..core.log import warn_once

DEFAULT_RESOLUTION = (640, 480)


def open_stage(path: str) -> Usd.Stage:
    """Open a USD stage, turning every failure into a one-line StageError."""
    if not os.path.exists(path):
        raise StageError(f"stage not found: {path}")
    if os.path.isdir(path):
        raise StageError(f"stage path is a directory: {path}")
    if not os.path.isfile(path):
        raise StageError(f"stage path is not a regular file: {path}")
    try:
        stage = Usd.Stage.Open(path)
    except (Tf.ErrorException, UnicodeDecodeError, RuntimeError) as exc:
        raise StageError(f"cannot read stage {path}: {usd_error_detail(exc)}") from None
    if stage is None:
        raise StageError(f"cannot read stage {path}")
    warn_composition_errors(stage, path)
    return stage


def warn_composition_errors(stage: Usd.Stage, path: str, shown: int = 2) -> None:
    """One warning naming the stage's composition errors (a reference, payload or sublayer that
    cannot be opened, a cycle): what they bring in is missing from the render, which still goes
    on, as usdview's would. The first `shown` distinct messages are quoted, the rest counted."""
    messages = list(dict.fromkeys(" ".join(str(err).split()).rstrip(".") for err in stage.GetCompositionErrors()))
    if not messages:
        return
    more = f" (and {len(messages) - shown} more)" if len(messages) > shown else ""
    noun = "error" if len(messages) == 1 else "errors"
    warn_once(f"composition:{os.path.abspath(path)}",
              f"{path}: {len(messages)} composition {noun}, rendering without what they would bring in: "
              + "; ".join(messages[:shown]) + more)


def usd_error_detail(exc: BaseException) -> str:
    """One line from a USD error: the parser's `line:column: what` when it names them (USD's
    internal namespaces dropped), else the first line of its text; USD text that is not UTF-8
    (a file with non-text bytes) becomes a plain statement."""
    not_text = "the file is not valid USD text (bytes that are not UTF-8)"
    if isinstance(exc, UnicodeDecodeError):
        return not_text
    try:
        text = str(exc)
    except UnicodeDecodeError:   # USD's message quotes the file's bytes
        return not_text
    text = re.sub(r"pxrInternal_v\w*?__pxrReserved__::|pxrInternal_v\w*?___", "", text)
    where = re.search(r":(\d+):(\d+): ([^\n']{0,160})", text)
    if where:
        return f"line {where.group(1)}, column {where.group(2)}: {where.group(3).strip()}"
    lines = [ln.strip() for ln in text.strip().splitlines() if ln.strip()]
    detail = next((ln for ln in lines if not ln.startswith("Error in")), "")
    if not detail and lines:   # "Error in '...' at line N in file F : 'message'"
        detail = lines[0].split(" : ", 1)[-1].strip("' ")
    return detail[:200] or "invalid USD"


def render_settings_prim(stage: Usd.Stage) -> UsdRender.Settings | None:
    """The stage's UsdRenderSettings: the one named in the stage metadata, else the first found."""
    settings = UsdRender.Settings.GetStageRenderSettings(stage)
    if settings and settings.GetPrim().IsValid():
        return settings
    for prim in stage.Traverse():
        if prim.IsA(UsdRender.Settings):
            return UsdRender.Settings(prim)
    return None


def choose_camera(stage: Usd.Stage, camera: str | None) -> UsdGeom.Camera:
    """SPEC §3: the argument, else the render settings' camera, else the first camera found, else
    a camera that frames the stage (framing.py; placed per frame by place_framing_camera)."""
    if camera == FRAMING_CAMERA_PATH:
        return define_framing_camera(stage)
    if camera:
        prim = stage.GetPrimAtPath(camera) if Sdf.Path.IsValidPathString(camera) else None
        if not prim or not prim.IsValid():
            raise StageError(f"camera {camera} not found in the stage")
        if not prim.IsA(UsdGeom.Camera):
            raise StageError(f"{camera} is a {prim.GetTypeName() or 'typeless prim'}, not a Camera")
        return UsdGeom.Camera(prim)
    settings = render_settings_prim(stage)
    if settings:
        targets = settings.GetCameraRel().GetTargets()
        if targets:
            prim = stage.GetPrimAtPath(targets[0])
            if prim and prim.IsA(UsdGeom.Camera):
                return UsdGeom.Camera(prim)
            warn_once(f"settings-camera:{targets[0]}",
                      f"render settings name camera {targets[0]}, which is not a Camera; using the first camera")
    for prim in stage.Traverse(Usd.TraverseInstanceProxies(Usd.PrimDefaultPredicate)):
        if prim.IsA(UsdGeom.Camera):
            return UsdGeom.Camera(prim)
    return define_framing_camera(stage)


def choose_resolution(stage: Usd.Stage, resolution: tuple[int, int] | None) -> tuple[int, int]:
    """SPEC §3: the argument, else UsdRenderSettings' resolution, else 640×480."""
    if resolution is None:
        settings = render_settings_prim(stage)
        res = settings.GetResolutionAttr().Get() if settings else None
        resolution = (int(res[0]), int(res[1])) if res is not None and settings.GetResolutionAttr().HasAuthoredValue() else DEFAULT_RESOLUTION
    w, h = resolution
    if w <= 0 or h <= 0 or w > 16384 or h > 16384:
        raise UserError(f"resolution must be between 1x1 and 16384x16384, got {w}x{h}")
    return int(w), int(h)


def projection_at(camera: UsdGeom.Camera, frame: float, resolution: tuple[int, int],
                  conform_policy: str = "expandAperture") -> Projection:
    """Camera intrinsics read at the frame time, conformed to the image aspect (SPEC §3)."""
    gf_cam: Gf.Camera = camera.GetCamera(Usd.TimeCode(frame))
    check_intrinsics(camera, gf_cam)   # before the window: a zero aperture has no aspect
    window = gf_cam.frustum.GetWindow()
    w, h = resolution
    win = conform_window((window.GetMin()[0], window.GetMin()[1], window.GetMax()[0], window.GetMax()[1]),
                         w / h, conform_policy)
    near, far = gf_cam.clippingRange.min, gf_cam.clippingRange.max
    if not (near > 0 and far > near and math.isfinite(near)):
        raise StageError(f"camera {camera.GetPath()} has an invalid clipping range ({near}, {far})")
    return Projection(orthographic=gf_cam.projection == Gf.Camera.Orthographic, window=win,
                      near=float(near), far=float(far), width=w, height=h)


def check_intrinsics(camera: UsdGeom.Camera, gf_cam: Gf.Camera) -> None:
    """Camera intrinsics a projection can be built from: finite, positive focal length and
    apertures, finite offsets within a sane bound (else a StageError naming the attribute)."""
    path = camera.GetPath()
    values = {"focalLength": gf_cam.focalLength, "horizontalAperture": gf_cam.horizontalAperture,
              "verticalAperture": gf_cam.verticalAperture}
    for name, v in values.items():
        if not (math.isfinite(v) and 0 < v < 1e12):
            raise StageError(f"camera {path} has an invalid {name} ({v}): it must be a finite positive number")
    for name, v in (("horizontalApertureOffset", gf_cam.horizontalApertureOffset),
                    ("verticalApertureOffset", gf_cam.verticalApertureOffset)):
        if not (math.isfinite(v) and abs(v) < 1e6 * max(values["horizontalAperture"], values["verticalAperture"])):
            raise StageError(f"camera {path} has an invalid {name} ({v})")


#: The widest shutter accepted, in time codes: wider ones ask for unbounded motion sampling.
MAX_SHUTTER_SPAN = 1000.0


def conform_policy(stage: Usd.Stage) -> str:
    settings = render_settings_prim(stage)
    if settings:
        policy = settings.GetAspectRatioConformPolicyAttr().Get()
        if policy:
            return str(policy)
    return "expandAperture"


@dataclass(frozen=True)
class Shutter:
    """The exposure interval of a frame in time codes; `exposed` is False when close < open."""

    open: float
    close: float

    @property
    def exposed(self) -> bool:
        return self.close >= self.open

    @property
    def instant(self) -> bool:
        return self.close == self.open

    def time(self, u: float) -> float:
        """USD time code at shutter fraction u in [0, 1]."""
        return self.open + u * (self.close - self.open)


def shutter_for_frame(stage: Usd.Stage, camera: UsdGeom.Camera, frame: float,
                      override: tuple[float, float] | None) -> Shutter:
    """SPEC §2: [F + open, F + close] from the camera (or --shutter); warnings for odd cases."""
    settings = render_settings_prim(stage)
    if settings and settings.GetDisableMotionBlurAttr().Get():
        return Shutter(frame, frame)
    if override is not None:
        o, c = override
    else:
        open_attr, close_attr = camera.GetShutterOpenAttr(), camera.GetShutterCloseAttr()
        if not (open_attr.HasAuthoredValue() or close_attr.HasAuthoredValue()):
            warn_once(f"shutter:{camera.GetPrim().GetStage().GetRootLayer().identifier}:{camera.GetPath()}",
                      f"camera {camera.GetPath()} has no authored shutter: USD's fallback [0, 0] renders a sharp frame "
                      f"(use --shutter OPEN:CLOSE to blur)")
        o, c = _shutter_value(open_attr, frame), _shutter_value(close_attr, frame)
    if not (math.isfinite(o) and math.isfinite(c)):
        raise StageError(f"camera {camera.GetPath()} has a non-finite shutter ({o}, {c})")
    if abs(o) > MAX_SHUTTER_SPAN or abs(c) > MAX_SHUTTER_SPAN or c - o > MAX_SHUTTER_SPAN:
        raise StageError(f"shutter [{o:g}, {c:g}] is wider than {MAX_SHUTTER_SPAN:g} frames around the frame "
                         f"(check the camera's shutter:open/close or --shutter)")
    if c < o:
        warn_once(f"shutter-neg:{camera.GetPath()}:{o}:{c}",
                  f"shutter close ({c}) is before open ({o}): no exposure, the frame is black")
    return Shutter(frame + o, frame + c)


def _shutter_value(attr: Usd.Attribute, frame: float) -> float:
    """A shutter offset as a float (0 when unauthored; NaN when not a number, refused later)."""
    value = attr.Get(Usd.TimeCode(frame))
    try:
        return float(value) if value is not None else 0.0
    except (TypeError, ValueError):
        return math.nan


def parse_shutter(text: str) -> tuple[float, float]:
    """'OPEN:CLOSE' -> (open, close) offsets."""
    parts = text.split(":")
    try:
        if len(parts) != 2:
            raise ValueError
        o, c = float(parts[0]), float(parts[1])
        if not (math.isfinite(o) and math.isfinite(c)):
            raise ValueError
    except ValueError:
        raise UserError(f"bad shutter '{text}': expected OPEN:CLOSE, e.g. -0.25:0.25") from None
    return o, c


def parse_resolution(text: str) -> tuple[int, int]:
    """'WxH' -> (W, H), positive."""
    m = re.fullmatch(r"\s*(-?\d+)\s*[xX]\s*(-?\d+)\s*", text)
    if not m:
        raise UserError(f"bad resolution '{text}': expected WxH, e.g. 640x480")
    w, h = int(m.group(1)), int(m.group(2))
    if w <= 0 or h <= 0:
        raise UserError(f"bad resolution '{text}': width and height must be positive")
    return w, h


_NUM = r"[-+]?(?:\d+(?:\.\d*)?|\.\d+)"
_FRAME_SPEC = re.compile(rf"{_NUM}(?::{_NUM}(?:x{_NUM})?)?")


MAX_FRAMES = 100_000


def parse_frames(spec: str) -> list[float]:
    """usdrecord frame specs: '1:24', '1:24x2', '1,5,9' (parsed by USD's own TimeCodeRange).

    Each part is checked against the grammar first: USD's parser crashes on some malformed
    specs (e.g. '1:') instead of raising.
    """
    frames: list[float] = []
    for part in spec.split(","):
        part = part.strip()
        if not _FRAME_SPEC.fullmatch(part):
            raise UserError(f"bad frame spec '{spec}': expected e.g. 1:24, 1:24x2 or 1,5,9")
        try:
            rng = UsdUtils.TimeCodeRange.CreateFromFrameSpec(part)
        except Tf.ErrorException:
            raise UserError(f"bad frame spec '{spec}': expected e.g. 1:24, 1:24x2 or 1,5,9") from None
        if not rng.IsValid():
            raise UserError(f"bad frame spec '{spec}'")
        stride = rng.stride
        count = 1 if stride == 0 else math.floor((rng.endTimeCode.GetValue() - rng.startTimeCode.GetValue())
                                                 / stride + 1e-9) + 1
        if count + len(frames) > MAX_FRAMES:
            raise UserError(f"frame spec '{spec}' selects {count:,} frames (at most {MAX_FRAMES:,} per run)")
        frames.extend(float(t.GetValue()) for t in rng)
    if not frames:
        raise UserError(f"frame spec '{spec}' selects no frame")
    return frames


_HASH_RUN = re.compile(r"(#+)(?:\.(#+))?")


def output_path_for_frame(pattern: str, frame: float, num_frames: int) -> str:
    """Replace the run of '#' in `pattern` by the zero-padded frame ('###.###' for sub-frames)."""
    m = None
    for m in _HASH_RUN.finditer(pattern):
        pass
    if m is None:
        if num_frames > 1:
            raise UserError(f"output '{pattern}' has no '#' run but {num_frames} frames are rendered "
                            f"(e.g. out/shot.####.exr)")
        return pattern
    int_width = len(m.group(1))
    frac = m.group(2)
    if frac:
        text = f"{frame:0{int_width + 1 + len(frac)}.{len(frac)}f}"
    else:
        if frame != int(frame):
            raise UserError(f"frame {frame} is a sub-frame: the output needs a '###.###' pattern")
        text = f"{int(frame):0{int_width}d}"
    return pattern[:m.start()] + text + pattern[m.end():]


def _up_the_namespace(prim: Usd.Prim, test, memo: dict) -> bool:
    """True when test(p) holds for the prim or an ancestor; memo (path -> verdict) is filled for
    every prim walked, so prims sharing ancestors walk each of them once."""
    walked = []
    p, verdict = prim, False
    while p and p.IsValid() and not p.IsPseudoRoot():
        known = memo.get(p.GetPath())
        if known is not None:
            verdict = known
            break
        walked.append(p.GetPath())
        if test(p):
            verdict = True
            break
        p = p.GetParent()
    for path in walked:   # every prim walked below one that passes the test passes too
        memo[path] = verdict
    return verdict


def _visibility_animated(p: Usd.Prim) -> bool:
    return p.IsA(UsdGeom.Imageable) and UsdGeom.Imageable(p).GetVisibilityAttr().ValueMightBeTimeVarying()


def _transform_animated(p: Usd.Prim) -> bool:
    return p.IsA(UsdGeom.Xformable) and UsdGeom.Xformable(p).TransformMightBeTimeVarying()


def visibility_varies(prims: list[Usd.Prim], memo: dict | None = None) -> bool:
    """True when the visibility of any of `prims` or of an ancestor may change over time (an
    animated `visibility` attribute); else every time's ComputeVisibility gives the same answer.
    memo (path -> verdict, one dict for this question only) shares ancestors between calls."""
    memo = {} if memo is None else memo
    return any(_up_the_namespace(prim, _visibility_animated, memo) for prim in prims)


def transform_may_vary(prim: Usd.Prim, memo: dict | None = None) -> bool:
    """True when the prim's local-to-world transform may change over time: an xformOp of its own
    or of an ancestor may take different values at different times (time samples, value clips,
    splines). memo (path -> verdict, one dict for this question only) shares ancestors between calls."""
    return _up_the_namespace(prim, _transform_animated, {} if memo is None else memo)


def prims_visible(prims: list[Usd.Prim], time: float) -> bool:
    """True when none of `prims` is invisible at USD time `time` (ancestors included)."""
    t = Usd.TimeCode(time)
    return all(UsdGeom.Imageable(p).ComputeVisibility(t) != UsdGeom.Tokens.invisible for p in prims)

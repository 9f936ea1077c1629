"""`render()`: the whole pipeline in one readable function, with per-stage timings in `stats`.

stage -> camera, resolution, shutter -> scene (static tables) -> method (snapshots over the
shutter, visibility over time, shading) -> AOVs -> result.
"""

from __future__ import annotations

import math
import os
import sys
import threading
import time
from dataclasses import dataclass, field

import numpy as np
import warp as wp
from pxr import Tf

from .core import log, progress
from .core.allocator import keep_freed_memory
from .core.parallel import Background, default_threads
from .methods.frame import FrameContext
from .usd.framing import FRAMING_CAMERA_PATH, is_framing_camera, place_framing_camera
from .core.errors import SettingsError, StageError, UserError
from .output.exr_attributes import standard_attributes
from .core.memory import check_frame_fits
from .methods import KERNEL_MODULES, get_method
from .methods.aovs import aov_snapshots, depth_motion
from .core.preload import preload_modules
from .usd.material_cache import MaterialCache
from .usd.unit_cache import UnitCache
from .usd.scene import Scene, UnitsDroppedMidFrame
from .core.settings import RenderSettings
from .usd.stage import (choose_camera, choose_resolution, conform_policy, open_stage, projection_at,
                    shutter_for_frame)

from .core.version import __version__


@dataclass
class RenderResult:
    """A rendered frame.

    rgba: (H, W, 4) float32 linear RGBA (RGB premultiplied by coverage over a black background).
    aovs: name -> array: "Z" (H, W) view depth, "motion" (H, W, 2) pixels open->close,
          "coverage" (H, W) time-averaged coverage.
    stats: timings per stage (seconds), triangles, method counters, warnings.
    metadata: camera, shutter, method and settings (written to the EXR header as warp_blur.*).
    exr_attributes: OpenEXR standard attributes (worldToCamera, worldToNDC, chromaticities, ...).
    """

    rgba: np.ndarray
    aovs: dict = field(default_factory=dict)
    stats: dict = field(default_factory=dict)
    metadata: dict = field(default_factory=dict)
    exr_attributes: dict = field(default_factory=dict)


_warp_ready = False


def init_warp(device: str) -> None:
    """Initialise Warp once. The native CUDA probe's stderr notice is silenced (so a user error
    stays one line); a requested device that does not exist here is a user error. Freed frame
    buffers are kept for the next frame from here on (core/allocator.py)."""
    global _warp_ready
    if not _warp_ready:
        keep_freed_memory()
        sys.stderr.flush()
        saved = os.dup(2)
        try:
            with open(os.devnull, "w") as null:
                os.dup2(null.fileno(), 2)
                wp.init()
        finally:
            os.dup2(saved, 2)
            os.close(saved)
        _warp_ready = True
    names = {str(d) for d in wp.get_devices()} | {str(d).split(":")[0] for d in wp.get_devices()}
    if device not in names:
        raise SettingsError(f"device '{device}' is not available here (available: {', '.join(sorted(names))})")


def usd_error_text(exc: Exception) -> str:
    """USD's message in a Tf.ErrorException, on one line (without the source file and line)."""
    lines = [ln.strip() for ln in str(exc).splitlines() if ln.strip()]
    text = lines[-1] if lines else type(exc).__name__
    return text.rsplit(" : ", 1)[-1].strip() or text


class Renderer:
    """A stage opened once and rendered at many frames with the same settings."""

    def __init__(self, scene_path: str, *, camera: str | None = None,
                 resolution: tuple[int, int] | None = None, settings: RenderSettings | None = None) -> None:
        # this Renderer's warnings: said once each here, whatever other stages and Renderers in
        # the process said, and only here (core/log.py)
        self._warnings = log.WarningScope()
        with log.scope(self._warnings):
            self._open(scene_path, camera, resolution, settings)
        # what opening the stage said (its computed camera, its shutter), for the first frame's stats
        self._opening_warnings = self._warnings.take()

    def _open(self, scene_path: str, camera: str | None, resolution: tuple[int, int] | None,
              settings: RenderSettings | None) -> None:
        """Open the stage and choose the camera, resolution and caches (in the Renderer's scope)."""
        self.settings = settings or RenderSettings()
        self.scene_path = scene_path
        self.stage = open_stage(scene_path)
        self.camera = choose_camera(self.stage, camera)
        self.resolution = choose_resolution(self.stage, resolution)
        self.conform = conform_policy(self.stage)
        check_frame_fits(self.settings.method, *self.resolution, self.settings.spatial_samples,
                         self.settings.frame_memory_limit_mb)
        init_warp(self.settings.device)
        # material tables kept across frames while the stage's shading cannot change; the framing
        # camera placed each frame is no such change
        self.materials = MaterialCache(self.stage, ignored=FRAMING_CAMERA_PATH)
        # geometry units kept across frames where nothing they were read from can change
        self.units = UnitCache(self.stage, ignored=FRAMING_CAMERA_PATH)
        self._lock = threading.Lock()

    def check_frame(self, frame: float) -> None:
        """Frames that are not finite, or outside the stage's authored time range, are a user error
        (naming the range); the CLI and the API both refuse them here."""
        if not math.isfinite(frame):
            raise UserError(f"frame {frame} is not a finite number")
        if self.stage.HasAuthoredTimeCodeRange():
            start, end = self.stage.GetStartTimeCode(), self.stage.GetEndTimeCode()
            lo, hi = min(start, end), max(start, end)   # a reversed authored range still bounds the frames
            if not (lo <= frame <= hi):
                raise UserError(f"frame {frame:g} is outside the stage's authored range {lo:g}..{hi:g}")

    def default_frame(self) -> float:
        return float(self.stage.GetStartTimeCode()) if self.stage.HasAuthoredTimeCodeRange() else 1.0

    def render(self, frame: float) -> RenderResult:
        """Render one frame (a time code inside the stage's authored range). Calls from several
        threads take turns: a frame places the framing camera in the stage and may add to the
        kept material table (each frame still uses every core)."""
        with self._lock, log.scope(self._warnings):
            try:
                return self._render(frame)
            except BaseException as exc:
                self._warnings.take()   # a failed frame's warnings (logged with it) are not the next frame's
                if isinstance(exc, Tf.ErrorException):   # USD's own verification failing on the stage's data
                    raise StageError(f"USD cannot evaluate {self.scene_path} at frame {frame:g}: "
                                     f"{usd_error_text(exc)}") from None
                raise

    def _render(self, frame: float) -> RenderResult:
        t_start = time.perf_counter()
        frame = float(frame)
        self.check_frame(frame)
        s = self.settings
        device = s.device
        if is_framing_camera(self.camera):
            place_framing_camera(self.stage, self.camera, frame, self.resolution[0] / self.resolution[1])
        proj = projection_at(self.camera, frame, self.resolution, self.conform)
        shutter = shutter_for_frame(self.stage, self.camera, frame, s.shutter)
        t0 = time.perf_counter()
        progress.stage("load")
        scene = Scene(self.stage, self.camera, frame, shutter, skip_invalid=s.skip_invalid, proj=proj,
                      materials=self.materials.table_for(frame), kept_units=self.units,
                      sphere_error_px=s.resolved_sphere_error_px)
        if not scene.units:
            raise StageError(f"the stage {self.scene_path} has no renderable geometry "
                             f"(meshes, implicit gprims or point instancers)")
        load_s = time.perf_counter() - t0
        h, w = proj.height, proj.width
        for _attempt in range(len(scene.units) + 1):
            ctx = FrameContext(scene=scene, proj=proj, shutter=shutter, settings=s, device=device)
            ctx.timings["load"] = load_s
            try:
                rgba, aovs = self._frame_images(ctx)
                break
            except UnitsDroppedMidFrame:   # --skip-invalid dropped a prim some snapshot had shown
                ctx.release()
        else:   # (each retry drops one unit more: unreachable)
            raise RuntimeError("frame kept dropping prims")
        ctx.release()   # the frame's buffers go back now, for the next frame to reuse
        total = time.perf_counter() - t_start
        stats = {
            "method": s.method, "frame": frame, "resolution": [w, h],
            "triangles": scene.num_triangles, "prims": len(scene.units), "prims_reused": scene.units_reused,
            "time": {**{k: round(v, 6) for k, v in ctx.timings.items()}, "total": round(total, 6)},
            "triangles_per_second": scene.num_triangles / total if total > 0 else math.inf,
            **ctx.counters, "warnings": self._opening_warnings + self._warnings.take(),
        }
        self._opening_warnings = []
        metadata = {
            "camera": str(self.camera.GetPath()), "shutter": [shutter.open, shutter.close],
            "frame": frame, "scene": os.path.abspath(self.scene_path), "warp_blur_version": __version__,
            "settings": s.describe(), "render_time_s": round(total, 4), "error_estimate": stats["error_estimate"],
            "motion_convention": "motion.X/motion.Y: screen displacement in pixels of the surface seen at the "
                                 "shutter centre, from shutter open to close; x right, y down; 0 where nothing is seen",
        }
        exr = standard_attributes(proj, scene.cam_from_world(0.5 * (shutter.open + shutter.close)),
                                  self.stage.GetFramesPerSecond(), self.scene_path, frame)
        return RenderResult(rgba=rgba, aovs=aovs, stats=stats, metadata=metadata, exr_attributes=exr)

    def _frame_images(self, ctx: FrameContext) -> tuple[np.ndarray, dict[str, np.ndarray]]:
        """(rgba (H, W, 4) float32, AOVs by name) of the frame ctx holds: the method's image (the
        one sharp image when nothing moves) and the AOVs asked for."""
        s, shutter, proj = ctx.settings, ctx.shutter, ctx.proj
        h, w = proj.height, proj.width
        wants_aovs = shutter.exposed and ("Z" in s.aovs or "motion" in s.aovs)
        aov_job = None
        # the frame minus its half-sampled frame (methods/halves.py): 0 where every instant is alike
        ctx.counters["error_estimate"] = 0.0
        if not shutter.exposed:
            rgba = np.zeros((h, w, 4), np.float32)
        else:
            # the method's kernel modules built side by side (once a process; quick from the cache)
            preload_modules(KERNEL_MODULES[s.method], ctx.device, s.threads)
            static = ctx.static_frame()
            if static is not None:  # nothing moves: every method's answer is the one sharp image
                rgba = ctx.render_static(static, aovs=wants_aovs).reshape(h, w, 4).astype(np.float32)
            else:
                if wants_aovs and s.method != "velocity" and (s.threads or default_threads()) > 1:
                    # the Z/motion pass on a helper beside the method, from snapshots taken here
                    # (USD is read on this thread only): it fills the cores the method's host
                    # work leaves idle
                    snapshots = aov_snapshots(ctx)
                    _ = ctx.tables   # made here, not raced for by the helper and the method
                    aov_job = Background(lambda: depth_motion(ctx, snapshots), "aovs")
                try:
                    ctx.counters["error_estimate"] = None   # the method's own, if it has one
                    rgba = get_method(s.method)(ctx).reshape(h, w, 4).astype(np.float32)
                except BaseException:
                    if aov_job is not None:
                        aov_job.wait()   # the frame's buffers are released after: the helper is done first
                    raise
        aovs: dict[str, np.ndarray] = {}
        if not shutter.exposed:
            # no exposure sees nothing (SPEC §2): the layers asked for hold what they hold where
            # nothing is seen (SPEC §1), so a pipeline reading them finds them in every frame
            if "Z" in s.aovs:
                aovs["Z"] = np.full((h, w), np.inf, np.float32)
            if "motion" in s.aovs:
                aovs["motion"] = np.zeros((h, w, 2), np.float32)
        elif wants_aovs:
            if ctx.aov_motion is not None:  # the velocity method's or a still frame's own buffers
                depth, motion = ctx.aov_depth, ctx.aov_motion
            elif aov_job is not None:
                depth, motion = aov_job.result()
            else:
                depth, motion = depth_motion(ctx)
            if "Z" in s.aovs:
                aovs["Z"] = depth.astype(np.float32)
            if "motion" in s.aovs:
                aovs["motion"] = motion.astype(np.float32)
        if "coverage" in s.aovs:
            aovs["coverage"] = rgba[..., 3].copy()
        return rgba, aovs


def render(scene: str, frame: float | None = None, method: str = "accumulation",
           resolution: tuple[int, int] | None = None, camera: str | None = None, device: str = "cpu",
           settings: RenderSettings | None = None, **kwargs) -> RenderResult:
    """Render one frame of a USD stage (SPEC §6). Keyword settings are RenderSettings fields."""
    if settings is None:
        settings = RenderSettings(method=method, device=device, **kwargs)
    elif kwargs:
        settings = settings.replace(**kwargs)
    renderer = Renderer(scene, camera=camera, resolution=resolution, settings=settings)
    return renderer.render(renderer.default_frame() if frame is None else float(frame))

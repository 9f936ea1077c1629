"""`warp-blur info`: what a scene requires to render (camera, shutter, motion, lights, cost)."""

from __future__ import annotations

import numpy as np
from pxr import UsdGeom

from .lights import DISTANT, DISK, RECT, SPHERE
from .framing import is_framing_camera, place_framing_camera
from .scene import Scene
from .stage import (choose_camera, choose_resolution, conform_policy, open_stage, projection_at,
                    shutter_for_frame)

_LIGHT_NAMES = {DISTANT: "distant", SPHERE: "sphere", RECT: "rect", DISK: "disk"}


def scene_report(path: str, camera: str | None = None, frame: float | None = None,
                 resolution: tuple[int, int] | None = None) -> dict:
    """A dict describing the scene at `frame` (default: the stage's start time code)."""
    stage = open_stage(path)
    cam = choose_camera(stage, camera)
    res = choose_resolution(stage, resolution)
    if frame is None:
        frame = float(stage.GetStartTimeCode()) if stage.HasAuthoredTimeCodeRange() else 1.0
    if is_framing_camera(cam):
        place_framing_camera(stage, cam, frame, res[0] / res[1])
    shutter = shutter_for_frame(stage, cam, frame, None)
    proj = projection_at(cam, frame, res, conform_policy(stage))
    scene = Scene(stage, cam, frame, shutter, skip_invalid=True)
    open_s, close_s = scene.snapshot(shutter.open), scene.snapshot(shutter.close)
    prims = []
    px_open, px_close = proj.project(open_s.positions), proj.project(close_s.positions)
    for ui, u in enumerate(scene.units):
        o = scene.unit_vertex_offsets[ui]
        n = u.num_points * u.num_instances
        disp = np.linalg.norm(px_close[o:o + n] - px_open[o:o + n], axis=-1) if n else np.zeros(1)
        disp = disp[np.isfinite(disp)]
        prims.append({"path": u.path, "triangles": int(len(u.local_tris) * u.num_instances),
                      "instances": u.num_instances,
                      "deforming": bool(UsdGeom.PointBased(u.prim).GetPointsAttr().ValueMightBeTimeVarying())
                      if u.prim.IsA(UsdGeom.PointBased) else False,
                      "max_screen_motion_px": float(disp.max()) if len(disp) else 0.0,
                      "moves_on_screen": bool(len(disp) and disp.max() > 1e-3)})
    lights = [{"path": str(lp.prim.GetPath()), "type": _LIGHT_NAMES[lp.kind]} for lp in scene.light_prims]
    for row, info in zip(open_s.lights, lights):
        info["casts_shadows"] = bool(row[17] > 0.5)
    t = scene.num_triangles
    px = res[0] * res[1]
    memory = {
        "accumulation": int(t * 3 * 12 + px * 16 * 2 + t * 32),
        "stochastic": int(t * 3 * 12 * 2 + px * 16 * 2 + t * 32),
        "analytic": int(t * 3 * 12 * 2 + px * 16 * 2 + t * 32 + px * 4 * 32),
        "velocity": int(t * 3 * 12 * 3 + px * 16 * 4 + t * 32),
    }
    return {
        "scene": path, "camera": str(cam.GetPath()), "camera_computed": is_framing_camera(cam), "resolution": list(res),
        "projection": "orthographic" if proj.orthographic else "perspective",
        "frame_range": [stage.GetStartTimeCode(), stage.GetEndTimeCode()],
        "frames_per_second": stage.GetFramesPerSecond(), "frame": frame,
        "shutter": [shutter.open, shutter.close], "up_axis": UsdGeom.GetStageUpAxis(stage),
        "meters_per_unit": UsdGeom.GetStageMetersPerUnit(stage),
        "triangles": t, "prims": prims, "moving_prims": sum(p["moves_on_screen"] for p in prims),
        "lights": lights, "dome": scene.has_dome, "headlight": scene.headlight,
        "memory_estimate_bytes": memory,
    }


def format_report(r: dict) -> str:
    """Human-readable text of a scene report."""
    lines = [
        f"scene       {r['scene']}",
        f"camera      {r['camera']} ({r['projection']}{', computed to frame the stage' if r['camera_computed'] else ''}), "
        f"{r['resolution'][0]}x{r['resolution'][1]}",
        f"frames      {r['frame_range'][0]:g}..{r['frame_range'][1]:g} at {r['frames_per_second']:g} fps",
        f"shutter     [{r['shutter'][0]:g}, {r['shutter'][1]:g}] at frame {r['frame']:g}",
        f"stage       upAxis {r['up_axis']}, metersPerUnit {r['meters_per_unit']:g}",
        f"triangles   {r['triangles']} in {len(r['prims'])} prims, {r['moving_prims']} moving on screen",
    ]
    for p in r["prims"]:
        motion = f"moves up to {p['max_screen_motion_px']:.1f} px" if p["moves_on_screen"] else "static"
        extra = ", deforming" if p["deforming"] else ""
        inst = f" ×{p['instances']}" if p["instances"] > 1 else ""
        lines.append(f"  {p['path']}: {p['triangles']} tris{inst}, {motion}{extra}")
    if r["lights"]:
        for li in r["lights"]:
            lines.append(f"light       {li['path']} ({li['type']}{', shadows' if li.get('casts_shadows') else ''})")
    else:
        lines.append("light       none" + (" (headlight at the camera)" if r["headlight"] else ""))
    lines.append(f"dome        {'yes' if r['dome'] else 'no'}")
    lines.append("memory/frame " + ", ".join(f"{k} ~{v / 2**20:.1f} MiB" for k, v in r["memory_estimate_bytes"].items()))
    return "\n".join(lines)

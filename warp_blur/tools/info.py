"""`warp-blur info`: what a scene requires to render (camera, shutter, motion, lights, cost)."""

from __future__ import annotations

import numpy as np
from pxr import UsdGeom

from ..core.affine import invert_affine
from ..usd.lights import DISTANT, DISK, RECT, SPHERE
from ..usd.framing import is_framing_camera, place_framing_camera
from ..core.memory import frame_bytes
from ..usd.scene import Scene, UnitsDroppedMidFrame
from ..core.settings import METHODS
from ..usd.stage import (choose_camera, choose_resolution, conform_policy, open_stage, projection_at,
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
    # the projection makes spheres and subdivision meshes take the levels a render at `res` gives them
    scene = Scene(stage, cam, frame, shutter, skip_invalid=True, proj=proj)
    for _attempt in range(len(scene.units) + 1):
        try:
            open_s, close_s = scene.snapshot(shutter.open), scene.snapshot(shutter.close)
            break
        except UnitsDroppedMidFrame:   # invalid only at the close: both again without it
            continue
    prims = []
    motion = screen_motion(proj, open_s, close_s)
    for ui, u in enumerate(scene.units):
        o = scene.unit_vertex_offsets[ui]
        n = u.num_points * u.num_instances
        total, obj, cam_px = (_max_finite(m[o:o + n]) for m in motion)
        prims.append({"path": u.path, "triangles": int(len(u.local_tris) * u.num_instances),
                      "instances": u.num_instances,
                      "deforming": bool(UsdGeom.PointBased(u.prim).GetPointsAttr().ValueMightBeTimeVarying())
                      if u.prim.IsA(UsdGeom.PointBased) else False,
                      "max_screen_motion_px": total, "max_object_motion_px": obj, "max_camera_motion_px": cam_px,
                      "moves_in_world": obj > 1e-3,
                      "moves_on_screen": total > 1e-3})
    lights = [{"path": str(lp.prim.GetPath()), "type": _LIGHT_NAMES[lp.kind]} for lp in scene.light_prims]
    for row, info in zip(open_s.lights, lights):
        info["casts_shadows"] = bool(row[17] > 0.5)
    t = scene.num_triangles
    memory = {m: frame_bytes(m, res[0], res[1], 1, t) for m in METHODS}
    return {
        "scene": path, "camera": str(cam.GetPath()), "camera_computed": is_framing_camera(cam), "resolution": list(res),
        "projection": "orthographic" if proj.orthographic else "perspective",
        "frame_range": [stage.GetStartTimeCode(), stage.GetEndTimeCode()],
        "frames_per_second": stage.GetFramesPerSecond(), "frame": frame,
        "shutter": [shutter.open, shutter.close], "up_axis": UsdGeom.GetStageUpAxis(stage),
        "meters_per_unit": UsdGeom.GetStageMetersPerUnit(stage),
        "triangles": t, "prims": prims, "moving_prims": sum(p["moves_in_world"] for p in prims),
        "camera_moves": bool(np.abs(open_s.cam_from_world - close_s.cam_from_world).max() > 1e-9),
        "lights": lights, "dome": scene.has_dome,
        "dome_texture": scene.dome_map is not None, "headlight": scene.headlight,
        "memory_estimate_bytes": memory,
    }


def screen_motion(proj, open_s, close_s) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Per-vertex screen motion over the shutter, in pixels (V,): the whole of it; the object's
    own (the camera held at its shutter-open pose); and the camera's (the object held at open).
    NaN for vertices far outside the picture or behind the near plane."""
    def world(s):
        p = np.c_[s.positions, np.ones(len(s.positions))]
        return p @ invert_affine(s.cam_from_world)

    def px(points_world, cam_from_world):
        return proj.project((points_world @ cam_from_world)[:, :3])

    with np.errstate(all="ignore"):
        w_open, w_close = world(open_s), world(close_s)
        c_open, c_close = open_s.cam_from_world, close_s.cam_from_world
        base = px(w_open, c_open)
        total = np.linalg.norm(px(w_close, c_close) - base, axis=-1)
        obj = np.linalg.norm(px(w_close, c_open) - base, axis=-1)
        cam = np.linalg.norm(px(w_open, c_close) - base, axis=-1)
        # only points near the picture count: a vertex beside or behind the eye "moves" without bound
        w, h = proj.width, proj.height
        near_view = ((-open_s.positions[:, 2] > proj.near) & (-close_s.positions[:, 2] > proj.near)
                     & (base[:, 0] > -w) & (base[:, 0] < 2 * w) & (base[:, 1] > -h) & (base[:, 1] < 2 * h))
    return tuple(np.where(near_view, m, np.nan) for m in (total, obj, cam))


def _max_finite(values: np.ndarray) -> float:
    values = values[np.isfinite(values)]
    return float(values.max()) if len(values) else 0.0


def format_report(r: dict) -> str:
    """Human-readable text of a scene report."""
    lines = [
        f"scene       {r['scene']}",
        f"camera      {r['camera']} ({r['projection']}{', computed to frame the stage' if r['camera_computed'] else ''}), "
        f"{r['resolution'][0]}x{r['resolution'][1]}",
        f"frames      {r['frame_range'][0]:g}..{r['frame_range'][1]:g} at {r['frames_per_second']:g} fps",
        f"shutter     [{r['shutter'][0]:g}, {r['shutter'][1]:g}] at frame {r['frame']:g}",
        f"stage       upAxis {r['up_axis']}, metersPerUnit {r['meters_per_unit']:g}",
        f"triangles   {r['triangles']} in {len(r['prims'])} prims, {r['moving_prims']} moving in the world"
        f"{', the camera moves' if r['camera_moves'] else ''}",
    ]
    for p in r["prims"]:
        if not p["moves_on_screen"]:
            motion = "static"
        elif not p["moves_in_world"]:
            motion = f"still; the camera's motion moves it up to {p['max_camera_motion_px']:.1f} px"
        else:
            motion = f"moves up to {p['max_object_motion_px']:.1f} px by itself"
            if p["max_camera_motion_px"] > 1e-3:
                motion += f", {p['max_screen_motion_px']:.1f} px with the camera's motion"
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

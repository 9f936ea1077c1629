"""Precision report: where float32 kernels stand against float64, for one scene and instant.

Three checks: (1) the analytic method's coverage code (generic Warp functions) run in float32, as
the renderer runs it, and in float64 over (pixel, moving triangle) pairs of the frame: the largest
difference in covered shutter time; (2) the float32 render's view depth (Z AOV) and coverage at
the shutter centre against an independent float64 NumPy ray caster; (3) the same shot re-rendered
translated far from the origin (1e3 … 1e7 units): camera-relative float64 composition keeps the
image unchanged. (Shading and the rest of the pipeline are float32-only.)

    python bench/precision_report.py [--scene usd_scenes/demo.usda] [--frame 12] [--resolution 160x120]
"""

from __future__ import annotations

import argparse
import os
import sys
import tempfile

import numpy as np

HERE = os.path.dirname(os.path.abspath(__file__))
sys.path.insert(0, HERE)
from common import ROOT, save, table  # noqa: E402

import warp_blur as wb  # noqa: E402
from warp_blur.tools.precision import coverage_precision  # noqa: E402
from warp_blur.usd.scene import Scene  # noqa: E402
from warp_blur.usd.stage import choose_camera, open_stage, projection_at, shutter_for_frame  # noqa: E402


def float64_depth(scene_path: str, frame: float, res: tuple[int, int]) -> np.ndarray:
    """(H, W) nearest view depth at pixel centres (inf = nothing), in float64."""
    stage = open_stage(scene_path)
    cam = choose_camera(stage, None)
    proj = projection_at(cam, frame, res)
    shutter = shutter_for_frame(stage, cam, frame, None)
    scene = Scene(stage, cam, frame, shutter)
    snap = scene.snapshot(shutter.time(0.5))
    p = snap.positions
    tris = scene.tri_vertices[snap.tri_visible]
    a, b, c = p[tris[:, 0]], p[tris[:, 1]], p[tris[:, 2]]
    n = np.cross(b - a, c - a)
    w, h = res
    depth = np.full(h * w, np.inf)
    ys, xs = np.mgrid[0:h, 0:w]
    wx, wy = proj.pixel_window_coords(xs.ravel() + 0.5, ys.ravel() + 0.5)
    for start in range(0, h * w, 512):
        d = np.stack([wx[start:start + 512], wy[start:start + 512], -np.ones(len(wx[start:start + 512]))], 1)
        with np.errstate(divide="ignore", invalid="ignore"):
            t = (np.einsum("tk,tk->t", a, n)[None]) / (d @ n.T)
            e1 = np.einsum("pk,tk->pt", d, np.cross(a, b))
            e2 = np.einsum("pk,tk->pt", d, np.cross(b, c))
            e3 = np.einsum("pk,tk->pt", d, np.cross(c, a))
        inside = ((e1 > 0) & (e2 > 0) & (e3 > 0)) | ((e1 < 0) & (e2 < 0) & (e3 < 0))
        ok = inside & (t >= proj.near) & (t <= proj.far)
        depth[start:start + 512] = np.where(ok, t, np.inf).min(axis=1)
    return depth.reshape(h, w)


def translated_copy(scene_path: str, offset: float) -> str:
    """The stage wrapped in a parent transform that moves everything (camera included) by offset."""
    from pxr import Gf, Usd, UsdGeom
    folder = tempfile.mkdtemp()
    path = os.path.join(folder, "far.usda")
    stage = Usd.Stage.CreateNew(path)
    root = UsdGeom.Xform.Define(stage, "/Far")
    root.AddTranslateOp().Set(Gf.Vec3d(offset, offset, offset))
    src = Usd.Stage.Open(scene_path)
    prim = stage.OverridePrim("/Far/World")
    prim.GetReferences().AddReference(os.path.abspath(scene_path), src.GetDefaultPrim().GetPath())
    stage.SetStartTimeCode(src.GetStartTimeCode())
    stage.SetEndTimeCode(src.GetEndTimeCode())
    stage.SetTimeCodesPerSecond(src.GetTimeCodesPerSecond())
    stage.GetRootLayer().Save()
    return path


def main() -> None:
    ap = argparse.ArgumentParser()
    ap.add_argument("--scene", default=os.path.join(ROOT, "usd_scenes", "demo.usda"))
    ap.add_argument("--frame", type=float, default=12)
    ap.add_argument("--resolution", default="160x120")
    args = ap.parse_args()
    res = tuple(int(x) for x in args.resolution.split("x"))
    cov = coverage_precision(args.scene, args.frame, res)
    rows = [{"check": "analytic covered time, float32 vs float64 run of the same code", "pixels": cov.pairs,
             "max_abs": cov.max_dt, "max_rel": cov.mean_dt, "coverage_mismatch_px": cov.piece_mismatches}]
    r32 = wb.render(args.scene, frame=args.frame, resolution=res, samples=1, shutter=(0.0, 0.0))
    z32 = r32.aovs["Z"]
    z64 = float64_depth(args.scene, args.frame, res)
    both = np.isfinite(z32) & np.isfinite(z64)
    rows += [{"check": "view depth, float32 kernel vs float64", "pixels": int(both.sum()),
             "max_abs": float(np.abs(z32[both] - z64[both]).max()),
             "max_rel": float((np.abs(z32[both] - z64[both]) / z64[both]).max()),
             "coverage_mismatch_px": int((np.isfinite(z32) != np.isfinite(z64)).sum())}]
    base = wb.render(args.scene, frame=args.frame, resolution=res, method="analytic", aovs=()).rgba
    for offset in (1e3, 1e5, 1e6, 1e7):
        far = wb.render(translated_copy(args.scene, offset), frame=args.frame, resolution=res, method="analytic",
                        aovs=()).rgba
        rows.append({"check": f"analytic image moved {offset:g} units from the origin", "pixels": base.shape[0] * base.shape[1],
                     "max_abs": float(np.abs(far - base).max()),
                     "max_rel": float(np.sqrt(np.mean((far - base) ** 2)))})
    print(f"precision report: {os.path.basename(args.scene)} frame {args.frame:g} at {res[0]}x{res[1]}"
          " (pixels = pairs and max_rel = mean for the covered time, in shutter fractions; max_rel is the RMSE for"
          " the moved images; coverage_mismatch_px counts pairs with a different number of covered pieces)")
    print(table(rows, ["check", "pixels", "max_abs", "max_rel", "coverage_mismatch_px"]))
    print("saved", save("precision.json", rows))


if __name__ == "__main__":
    main()

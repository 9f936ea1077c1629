"""Thousands of animated props (a rigid-body export: each a cube under its own Xform, translated
and turned over the frame range), rendered over a few frames: what a frame costs with the moving
prims' transforms batched from their xformOps (usd/xform_ops.py) against asking USD for each prim
at each snapshot (units.BATCH_XFORM_OPS = False), for every method, in one run.

    python bench/bench_props.py [--props 3000] [--resolution 640x480] [--frames 3]
"""

from __future__ import annotations

import argparse
import os
import sys


sys.path.insert(0, os.path.dirname(__file__))
sys.path.insert(0, os.path.join(os.path.dirname(os.path.dirname(os.path.abspath(__file__))), "stages"))
from common import OUT, a_against_b, median_frame_seconds, save, table  # noqa: E402

import warp_blur as wb  # noqa: E402
import warp_blur.usd.units as units  # noqa: E402


def make_props(path: str, props: int) -> str:
    """`props` unit cubes in a grid, each Xform translated 3 units and turned a full circle about
    y over frames 0..24 (two samples each), a lit material, a sun with shadows and a dome."""
    from authoring import add_camera, add_distant_light, add_dome, add_material, new_stage
    from pxr import Gf, UsdGeom, UsdShade
    stage = new_stage(path, end=24)
    side = int(props ** 0.5) + 1
    add_camera(stage, translate=(0, 0, side * 2.2), shutter=(-0.25, 0.25))
    add_dome(stage)
    add_distant_light(stage, "/World/Sun", intensity=2.0)
    look = add_material(stage, "/World/Looks/M", diffuse=(0.6, 0.5, 0.3))
    for i in range(props):
        x, y = 2.0 * (i % side) - side, 2.0 * (i // side) - side
        xf = UsdGeom.Xform.Define(stage, f"/World/Props/P{i}")
        t = xf.AddTranslateOp()
        t.Set(Gf.Vec3d(x, y, 0), 0)
        t.Set(Gf.Vec3d(x + 3, y, 0), 24)
        r = xf.AddRotateYOp()
        r.Set(0.0, 0)
        r.Set(360.0, 24)
        cube = UsdGeom.Cube.Define(stage, f"/World/Props/P{i}/Cube")
        UsdShade.MaterialBindingAPI.Apply(cube.GetPrim()).Bind(look)
    stage.GetRootLayer().Save()
    return path


def frame_seconds(path: str, res: tuple[int, int], method: str, frames: list[float], batched: bool) -> float:
    """Median seconds a frame over `frames` (after a warm-up frame) on one Renderer."""
    units.BATCH_XFORM_OPS = batched
    try:
        r = wb.Renderer(path, resolution=res, settings=wb.RenderSettings(method=method, aovs=()))
        return median_frame_seconds(r.render, frames)
    finally:
        units.BATCH_XFORM_OPS = True


def main() -> None:
    ap = argparse.ArgumentParser()
    ap.add_argument("--props", type=int, default=3000)
    ap.add_argument("--resolution", default="640x480")
    ap.add_argument("--frames", type=int, default=3, help="frames timed after a warm-up frame")
    args = ap.parse_args()
    res = tuple(int(v) for v in args.resolution.split("x"))
    os.makedirs(os.path.join(OUT, "scenes"), exist_ok=True)
    path = make_props(os.path.join(OUT, "scenes", f"props_{args.props}.usda"), args.props)
    frames = [float(f) for f in range(2, 2 + args.frames)]
    rows = a_against_b(lambda method, batched: frame_seconds(path, res, method, frames, batched),
                       ("batched s", "per-prim s"), "props")
    print(f"\n{args.props} animated props at {res[0]}x{res[1]}, median of {args.frames} frames a row")
    print(table(rows, ["method", "batched s", "per-prim s", "per-prim / batched"]))
    print("saved", save("props.json", {"props": args.props, "resolution": res, "rows": rows}))


if __name__ == "__main__":
    main()

"""A dressed set: thousands of still props and one moving prop, rendered over a frame range. What a
frame costs when the Renderer keeps the props' units and still transforms from frame to frame
(usd/unit_cache.py, usd/units.py) against reading every prim again each frame (Renderer.units =
None), for every method, in one run.

    python bench/bench_set.py [--props 2000] [--resolution 640x480] [--frames 6]
"""

from __future__ import annotations

import argparse
import os
import sys


sys.path.insert(0, os.path.dirname(__file__))
sys.path.insert(0, os.path.join(os.path.dirname(os.path.dirname(os.path.abspath(__file__))), "stages"))
from common import OUT, a_against_b, median_frame_seconds, save, table  # noqa: E402

import warp_blur as wb  # noqa: E402


def make_set(path: str, props: int) -> str:
    """`props` still quads in a grid (five lit materials) behind a quad crossing the view, a sun
    and a dome, camera still; frames 0..24."""
    from authoring import add_camera, add_distant_light, add_dome, add_material, add_quad, new_stage
    stage = new_stage(path, end=24)
    side = int(props ** 0.5) + 1
    add_camera(stage, translate=(0, 0, side * 0.9), shutter=(-0.25, 0.25))
    add_dome(stage)
    add_distant_light(stage, "/World/Sun", intensity=2.0)
    looks = [add_material(stage, f"/World/Looks/M{i}", diffuse=(0.2 + 0.15 * i, 0.5, 0.3)) for i in range(5)]
    for i in range(props):
        x, y = i % side, i // side
        add_quad(stage, f"/World/Set/Prop{i}", 0.4, 0.4, material=looks[i % 5], translate=(x - side / 2, y - side / 2, -5))
    add_quad(stage, "/World/Mover", side / 8, side / 8, material=looks[0],
             translate_samples={0: (-side / 2, 0, 0), 24: (side / 2, 0, 0)})
    stage.GetRootLayer().Save()
    return path


def frame_seconds(path: str, res: tuple[int, int], method: str, frames: list[float], keep: bool) -> float:
    """Median seconds a frame over `frames` (after a warm-up frame) on one Renderer."""
    r = wb.Renderer(path, resolution=res, settings=wb.RenderSettings(method=method, aovs=()))
    if not keep:
        r.units = None   # every prim read again each frame
    return median_frame_seconds(r.render, frames)


def main() -> None:
    ap = argparse.ArgumentParser()
    ap.add_argument("--props", type=int, default=2000)
    ap.add_argument("--resolution", default="640x480")
    ap.add_argument("--frames", type=int, default=6, help="frames timed after a warm-up frame")
    args = ap.parse_args()
    res = tuple(int(v) for v in args.resolution.split("x"))
    os.makedirs(os.path.join(OUT, "scenes"), exist_ok=True)
    path = make_set(os.path.join(OUT, "scenes", f"set_{args.props}.usda"), args.props)
    frames = [float(f) for f in range(2, 2 + args.frames)]
    rows = a_against_b(lambda method, keep: frame_seconds(path, res, method, frames, keep), ("kept s", "read s"), "set")
    print(f"\n{args.props} still props + 1 mover at {res[0]}x{res[1]}, median of {args.frames} frames a row")
    print(table(rows, ["method", "kept s", "read s", "read / kept"]))
    print("saved", save("set.json", {"props": args.props, "resolution": res, "rows": rows}))


if __name__ == "__main__":
    main()

"""The lit default path: each method's frame with the stage's shadows (`--shadows auto`, the
default) against the same frame with shadows off, and a shadow map's cost per texel against the
camera's sharp render per pixel — all measured in one run (issue 15's guard).

    python bench/bench_default_path.py [--resolution 640x480] [--repeats 3] [--accuracy]

With --accuracy it also renders demo, shadows and near_plane at 320x240 and reports each
method's RMSE against accumulation-256 with `--shadows direct` (a map per instant: the reference).
"""

from __future__ import annotations

import argparse
import os
import sys

from tqdm import tqdm

sys.path.insert(0, os.path.dirname(__file__))
from common import SCENES, save, table, timed_median  # noqa: E402

import warp_blur as wb  # noqa: E402
from warp_blur.output.metrics import rmse  # noqa: E402

SCENE_FRAMES = {"demo": 12.0, "large": 2.0}
METHODS = (("analytic", {}), ("stochastic", {"samples": 64}), ("accumulation", {"samples": 64}))


def frame_time(scene: str, frame: float, res: tuple[int, int], repeats: int, **settings):
    renderer = wb.Renderer(os.path.join(SCENES, f"{scene}.usda"), resolution=res,
                           settings=wb.RenderSettings(aovs=(), **settings))
    if repeats == 0:   # one render, untimed use
        return 0.0, renderer.render(frame)
    return timed_median(lambda: renderer.render(frame), repeats=repeats, long_run_s=30.0)


def speed(res: tuple[int, int], repeats: int) -> list[dict]:
    rows = []
    cases = [(s, m, k) for s in SCENE_FRAMES for m, k in METHODS]
    for scene, method, knobs in tqdm(cases, desc="shadows on/off", unit="case"):
        frame = SCENE_FRAMES[scene]
        on_s, on = frame_time(scene, frame, res, repeats, method=method, **knobs)
        off_s, off = frame_time(scene, frame, res, repeats, method=method, shadows="off", **knobs)
        st = on.stats
        maps = st.get("shadow_maps_rendered", 0) + st.get("shadow_maps_warped", 0)
        texels = maps * st.get("shadow_map_size", 0) ** 2
        row = {"scene": scene, "method": method, "on_s": on_s, "off_s": off_s, "on/off": on_s / off_s,
               "maps": maps, "map_s": st["time"].get("shadows", 0.0),
               "warped_lights": str(st.get("shadow_warped_lights", "")).replace(" ", "")}
        if method == "accumulation":
            # the camera's sharp render per pixel: accumulation without shadows, per instant and pixel
            px = off.stats.get("instants", 64) * res[0] * res[1]
            row["pixel_ns"] = 1e9 * off.stats["time"]["render"] / px
        if texels:
            row["texel_ns"] = 1e9 * st["time"].get("shadow_render", 0.0) / texels
        rows.append(row)
    for scene in SCENE_FRAMES:   # texel cost against the same scene's camera pixel cost
        px = next(r["pixel_ns"] for r in rows if r["scene"] == scene and "pixel_ns" in r)
        for r in rows:
            if r["scene"] == scene and "texel_ns" in r:
                r["texel/pixel"] = r["texel_ns"] / px
    return rows


def accuracy() -> list[dict]:
    rows = []
    res = (320, 240)
    cases = [("demo", 12.0), ("shadows", 6.0), ("near_plane", 2.0)]
    for scene, frame in tqdm(cases, desc="accuracy", unit="scene"):
        _, ref = frame_time(scene, frame, res, 0, method="accumulation", samples=256, shadows="direct")
        for method, knobs in METHODS:
            _, got = frame_time(scene, frame, res, 0, method=method, **knobs)
            rows.append({"scene": scene, "method": method, "rmse_vs_acc256_direct": rmse(got.rgba, ref.rgba)})
    return rows


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--resolution", default="640x480")
    ap.add_argument("--repeats", type=int, default=3, help="renders per case after a warm-up (median)")
    ap.add_argument("--accuracy", action="store_true", help="also RMSE against accumulation-256 direct")
    ap.add_argument("--accuracy-only", action="store_true", help="only the RMSE table")
    args = ap.parse_args()
    res = tuple(int(x) for x in args.resolution.split("x"))
    out = {"resolution": res}
    if not args.accuracy_only:
        rows = speed(res, args.repeats)
        print(f"\nShadows on (auto) vs off, {res[0]}x{res[1]}, median of {args.repeats} (seconds; ratios in this run)")
        print(table(rows, ["scene", "method", "maps", "warped_lights", "map_s", "on_s", "off_s", "on/off",
                           "texel_ns", "pixel_ns", "texel/pixel"]))
        out["speed"] = rows
    args.accuracy = args.accuracy or args.accuracy_only
    if args.accuracy:
        acc = accuracy()
        print("\nRMSE against accumulation-256 with --shadows direct (320x240)")
        print(table(acc, ["scene", "method", "rmse_vs_acc256_direct"]))
        out["accuracy"] = acc
    save("default_path.json", out)


if __name__ == "__main__":
    main()

"""The lit default path: each method's frame with the stage's shadows (`--shadows auto`, the
default) against the same frame with shadows off, and a shadow map's cost per texel against the
camera's sharp render per pixel — all measured in one run (issue 15's guard).

    python bench/bench_default_path.py [--resolution 640x480] [--repeats 5] [--accuracy]

Each case's on and off frames are rendered alternately (on, off, on, off, ...) after a warm-up
of each, so a drift in the shared machine's load falls on both; `on/off` is the median of the
pairs' ratios, and `ratio_lo`-`ratio_hi` their spread.

With --accuracy it also renders demo, shadows and near_plane at 320x240 and reports each
method's RMSE against accumulation-256 with `--shadows direct` (a map per instant: the reference).
"""

from __future__ import annotations

import argparse
import os
import statistics
import sys
import time

from tqdm import tqdm

sys.path.insert(0, os.path.dirname(__file__))
from common import SCENES, save, table  # noqa: E402

import warp_blur as wb  # noqa: E402
from warp_blur.output.metrics import rmse  # noqa: E402

SCENE_FRAMES = {"demo": 12.0, "large": 2.0}
METHODS = (("analytic", {}), ("stochastic", {"samples": 64}), ("accumulation", {"samples": 64}))


def renderer(scene: str, res: tuple[int, int], **settings) -> wb.Renderer:
    return wb.Renderer(os.path.join(SCENES, f"{scene}.usda"), resolution=res,
                       settings=wb.RenderSettings(aovs=(), **settings))


def paired_times(scene: str, frame: float, res: tuple[int, int], repeats: int, **settings) -> dict:
    """The frame with shadows on (auto) and off, rendered alternately `repeats` times each after a
    warm-up of each: medians of both (seconds), the median, lowest and highest of the pairs'
    on/off ratios, and the last results."""
    on_r, off_r = renderer(scene, res, **settings), renderer(scene, res, shadows="off", **settings)
    on, off = on_r.render(frame), off_r.render(frame)
    on_t, off_t = [], []
    for _ in range(repeats):
        t0 = time.perf_counter()
        on = on_r.render(frame)
        t1 = time.perf_counter()
        off = off_r.render(frame)
        on_t.append(t1 - t0)
        off_t.append(time.perf_counter() - t1)
    ratios = [a / b for a, b in zip(on_t, off_t)]
    return {"on_s": statistics.median(on_t), "off_s": statistics.median(off_t), "on/off": statistics.median(ratios),
            "ratio_lo": min(ratios), "ratio_hi": max(ratios), "on": on, "off": off}


def speed(res: tuple[int, int], repeats: int) -> list[dict]:
    rows = []
    cases = [(s, m, k) for s in SCENE_FRAMES for m, k in METHODS]
    for scene, method, knobs in tqdm(cases, desc="shadows on/off", unit="case"):
        frame = SCENE_FRAMES[scene]
        timed = paired_times(scene, frame, res, repeats, method=method, **knobs)
        on, off = timed.pop("on"), timed.pop("off")
        st = on.stats
        maps = st.get("shadow_maps_rendered", 0) + st.get("shadow_maps_warped", 0)
        texels = maps * st.get("shadow_map_size", 0) ** 2
        row = {"scene": scene, "method": method, **timed, "maps": maps, "map_s": st["time"].get("shadows", 0.0),
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
        ref = renderer(scene, res, method="accumulation", samples=256, shadows="direct").render(frame)
        for method, knobs in METHODS:
            got = renderer(scene, res, method=method, **knobs).render(frame)
            rows.append({"scene": scene, "method": method, "rmse_vs_acc256_direct": rmse(got.rgba, ref.rgba)})
    return rows


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--resolution", default="640x480")
    ap.add_argument("--repeats", type=int, default=5, help="on/off pairs per case after a warm-up (medians)")
    ap.add_argument("--accuracy", action="store_true", help="also RMSE against accumulation-256 direct")
    ap.add_argument("--accuracy-only", action="store_true", help="only the RMSE table")
    args = ap.parse_args()
    res = tuple(int(x) for x in args.resolution.split("x"))
    out = {"resolution": res}
    if not args.accuracy_only:
        rows = speed(res, args.repeats)
        print(f"\nShadows on (auto) vs off, {res[0]}x{res[1]}, {args.repeats} alternated pairs (seconds: medians; "
              f"on/off: the pairs' median ratio, lo-hi their spread)")
        print(table(rows, ["scene", "method", "maps", "warped_lights", "map_s", "on_s", "off_s", "on/off",
                           "ratio_lo", "ratio_hi", "texel_ns", "pixel_ns", "texel/pixel"]))
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

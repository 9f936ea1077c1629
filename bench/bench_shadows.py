"""Shadows in motion: direct shadow maps (one rendered per instant) against maps warped from key
maps, across map sizes, control-point grids and area-light samples; time and error, one run.

Scene: usd_scenes/shadows.usda (a box translating and a slab spinning over a static ground, a
static sun and a moving rect lamp). Each row renders the frame with the analytic method (whose
own cost is small next to the shadows) and reports the shadow time, the whole frame's time, and
the RMSE of warped against direct at the same settings. A last table times accumulation (per
instant maps in direct mode) against analytic.

    python bench/bench_shadows.py [--quick] [--resolution 320x240] [--frame 6]
"""

from __future__ import annotations

import argparse
import csv
import os
import sys

import numpy as np
from tqdm import tqdm

sys.path.insert(0, os.path.dirname(__file__))
from common import OUT, SCENES, save, table, timed_median  # noqa: E402

import warp_blur as wb  # noqa: E402
from warp_blur.output.metrics import rmse  # noqa: E402


def run(renderer: wb.Renderer, frame: float, repeats: int) -> tuple[float, wb.RenderResult]:
    return timed_median(lambda: renderer.render(frame), repeats=repeats, long_run_s=10.0)


def main() -> None:
    ap = argparse.ArgumentParser()
    ap.add_argument("--quick", action="store_true", help="fewer and smaller cases")
    ap.add_argument("--resolution", default="320x240")
    ap.add_argument("--frame", type=float, default=6)
    ap.add_argument("--repeats", type=int, default=1)
    ap.add_argument("--scene", default=os.path.join(SCENES, "shadows.usda"))
    ap.add_argument("--no-methods", action="store_true", help="skip the methods table")
    args = ap.parse_args()
    res = tuple(int(x) for x in args.resolution.split("x"))
    scene = args.scene
    tag = os.path.splitext(os.path.basename(scene))[0]
    sizes = (256, 512) if args.quick else (256, 512, 1024, 2048)
    grids = (32, 128) if args.quick else (16, 32, 64, 128, 256, 512)
    samples = (1, 5) if args.quick else (1, 5, 9, 16)
    cases = [("map size", dict(shadow_map_size=s, shadow_grid=max(s // 4, 16))) for s in sizes]
    cases += [("grid", dict(shadow_map_size=512, shadow_grid=g)) for g in grids]
    cases += [("light samples", dict(shadow_map_size=512, light_samples=m)) for m in samples]
    rows = []
    for sweep, knobs in tqdm(cases, desc="shadow bench", unit="case"):
        row = {"sweep": sweep, **{k.replace("shadow_", ""): v for k, v in knobs.items()}}
        images = {}
        for mode in ("direct", "warped"):
            settings = wb.RenderSettings(method="analytic", aovs=(), shadows=mode, **knobs)
            renderer = wb.Renderer(scene, resolution=res, settings=settings)
            seconds, result = run(renderer, args.frame, args.repeats)
            images[mode] = result.rgba
            st = result.stats
            row[f"{mode}_shadow_s"] = st["time"].get("shadows", 0.0)
            row[f"{mode}_frame_s"] = seconds
            if mode == "warped":
                row["key_maps"] = st.get("shadow_key_maps", 0)
                row["warped_maps"] = st.get("shadow_maps_warped", 0)
                row["control_points"] = st.get("shadow_control_points", 0)
                row["warp_s"] = st["time"].get("shadow_warp", 0.0)
            else:
                row["direct_maps"] = st.get("shadow_maps_rendered", 0)
        row["speedup"] = row["direct_shadow_s"] / max(row["warped_shadow_s"], 1e-9)
        row["rmse_warped_vs_direct"] = rmse(images["warped"], images["direct"])
        row["max_warped_vs_direct"] = float(np.abs(images["warped"] - images["direct"]).max())
        rows.append(row)
    columns = ["sweep", "map_size", "grid", "light_samples", "direct_maps", "warped_maps", "key_maps", "control_points",
               "direct_shadow_s", "warped_shadow_s", "warp_s", "speedup", "direct_frame_s", "warped_frame_s",
               "rmse_warped_vs_direct", "max_warped_vs_direct"]
    print(f"\nShadows: analytic, {scene}, frame {args.frame:g}, {res[0]}x{res[1]} (seconds; ratios within this run)")
    print(table(rows, columns))

    # the methods with shadows: accumulation's direct mode renders a map per instant
    method_rows = []
    method_cases = [] if args.no_methods else [("accumulation", dict(samples=64)), ("stochastic", dict(samples=64)),
                                               ("analytic", {})]
    for method, knobs in tqdm(method_cases, desc="methods", unit="run"):
        for mode in ("direct", "warped", "off"):
            settings = wb.RenderSettings(method=method, aovs=(), shadows=mode, **knobs)
            seconds, result = run(wb.Renderer(scene, resolution=res, settings=settings), args.frame, args.repeats)
            method_rows.append({"method": method, "shadows": mode, "frame_s": seconds,
                                "shadow_s": result.stats["time"].get("shadows", 0.0),
                                "maps": result.stats.get("shadow_maps_rendered", 0) + result.stats.get("shadow_maps_warped", 0)})
    if method_rows:
        print("\nMethods with shadows (defaults: 512² maps, 8 map instants, 1 light sample)")
        print(table(method_rows, ["method", "shadows", "maps", "shadow_s", "frame_s"]))

    os.makedirs(OUT, exist_ok=True)
    with open(os.path.join(OUT, f"shadows_{tag}.csv"), "w", newline="") as f:
        w = csv.DictWriter(f, fieldnames=columns)
        w.writeheader()
        for r in rows:
            w.writerow({c: r.get(c, "") for c in columns})
    save(f"shadows_{tag}.json", {"cases": rows, "methods": method_rows, "resolution": res, "frame": args.frame})
    try:
        import matplotlib
        matplotlib.use("Agg")
        import matplotlib.pyplot as plt
        fig, ax = plt.subplots(figsize=(6, 4))
        for sweep in dict.fromkeys(r["sweep"] for r in rows):
            sel = [r for r in rows if r["sweep"] == sweep]
            ax.plot([r["warped_shadow_s"] for r in sel], [r["rmse_warped_vs_direct"] for r in sel], "o-", label=f"warped ({sweep})")
            ax.plot([r["direct_shadow_s"] for r in sel], [0.0] * len(sel), "x", label=f"direct ({sweep})")
        ax.set_xlabel("shadow time per frame (s)")
        ax.set_ylabel("RMSE warped vs direct")
        ax.legend(fontsize=7)
        fig.tight_layout()
        fig.savefig(os.path.join(OUT, f"shadows_{tag}.png"), dpi=120)
    except ImportError:
        print("(matplotlib not installed: no plot)")
    print(f"\nwrote {OUT}/shadows_{tag}.csv, .json, .png")


if __name__ == "__main__":
    main()

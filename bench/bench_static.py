"""Only what the scene requires: analytic (and the other methods) against the sharp render on a
fully static and a mostly static (95% of triangles still) version of the large scene, one run,
with the scene's sun casting shadows and without (--shadows auto,off).

The mostly static variant keeps 44 of the 870 rocks at the large scene's speeds (up to ~1 unit
and ~17° of spin per frame): a stress case for the analytic method's moving pixels; the slow
variant moves the same rocks at a quarter of those speeds.

    python bench/bench_static.py [--resolution 1024x768] [--repeats 5] [--shadows auto,off]
"""

from __future__ import annotations

import argparse
import os
import sys

from tqdm import tqdm

sys.path.insert(0, os.path.dirname(__file__))
sys.path.insert(0, os.path.join(os.path.dirname(os.path.dirname(os.path.abspath(__file__))), "stages"))
from common import OUT, save, table, timed_median  # noqa: E402

import make_large  # noqa: E402
import warp_blur as wb  # noqa: E402


def main() -> None:
    ap = argparse.ArgumentParser()
    ap.add_argument("--resolution", default="1024x768")
    ap.add_argument("--repeats", type=int, default=5, help="renders per row; the median is reported (the machine is shared and noisy)")
    ap.add_argument("--shadows", default="auto,off", help="comma-separated shadow modes to run")
    args = ap.parse_args()
    shadow_modes = [m for m in args.shadows.split(",") if m]
    res = tuple(int(x) for x in args.resolution.split("x"))
    os.makedirs(os.path.join(OUT, "scenes"), exist_ok=True)
    # name -> (share of rocks moving, speed): the stress case at the large scene's speeds, and the
    # same rocks at a quarter of them (a more common amount of blur)
    variants = {"static": (0.0, 1.0), "mostly_static": (0.05, 1.0), "mostly_static_slow": (0.05, 0.25)}
    rows = []
    cases = [(v, sm, m) for v in variants for sm in shadow_modes
             for m in ("sharp", "analytic", "stochastic", "accumulation", "velocity")]
    for variant, shadows, method in tqdm(cases, desc="static bench", unit="run"):
        path = os.path.join(OUT, "scenes", f"large_{variant}.usda")
        if not os.path.exists(path):
            make_large.main(path, moving_fraction=variants[variant][0], speed=variants[variant][1])
        if method == "sharp":
            settings = wb.RenderSettings(method="accumulation", samples=1, shutter=(0.0, 0.0), aovs=(),
                                         shadows=shadows)
        else:
            settings = wb.RenderSettings(method=method, aovs=(), shadows=shadows)
        renderer = wb.Renderer(path, resolution=res, settings=settings)
        seconds, result = timed_median(lambda: renderer.render(2.0), args.repeats)
        times = result.stats["time"]
        rows.append({"scene": variant, "shadows": shadows, "method": method, "seconds": seconds,
                     "triangles": result.stats["triangles"], "static_frame": result.stats.get("static_frame", False),
                     "shadow_s": times.get("shadows", 0.0),
                     "motion_px": result.stats.get("pixels_with_motion", ""),
                     "intervals_per_pixel": result.stats.get("intervals_per_pixel_mean", "")})
    for r in rows:
        sharp = next(x for x in rows if x["scene"] == r["scene"] and x["shadows"] == r["shadows"]
                     and x["method"] == "sharp")
        r["x_sharp"] = r["seconds"] / sharp["seconds"]
    print(f"large scene variants at {res[0]}x{res[1]}")
    print(table(rows, ["scene", "shadows", "method", "seconds", "x_sharp", "shadow_s", "static_frame", "motion_px",
                       "intervals_per_pixel", "triangles"]))
    print("saved", save("static.json", rows))


if __name__ == "__main__":
    main()

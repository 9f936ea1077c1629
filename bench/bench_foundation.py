"""Foundation benchmark: sharp render and accumulation on the demo at 640×480; per-stage timings,
triangles per second, and the speed-up of threaded tiles over one thread (measured in one run).

    python bench/bench_foundation.py [--resolution 640x480] [--samples 64] [--frame 12]
"""

from __future__ import annotations

import argparse
import os
import sys

from tqdm import tqdm

sys.path.insert(0, os.path.dirname(__file__))
from common import SCENES, save, table, timed_median  # noqa: E402

import warp_blur as wb  # noqa: E402
from warp_blur.core.parallel import default_threads  # noqa: E402


def main() -> None:
    ap = argparse.ArgumentParser()
    ap.add_argument("--resolution", default="640x480")
    ap.add_argument("--samples", type=int, default=64)
    ap.add_argument("--frame", type=float, default=12)
    ap.add_argument("--repeats", type=int, default=3)
    args = ap.parse_args()
    w, h = (int(x) for x in args.resolution.split("x"))
    scene = os.path.join(SCENES, "demo.usda")
    cores = default_threads()
    cases = [("sharp", 1, 1), ("sharp", 1, cores), ("accumulation", args.samples, 1),
             ("accumulation", args.samples, cores)]
    rows = []
    for name, samples, threads in tqdm(cases, desc="bench", unit="case"):
        renderer = wb.Renderer(scene, resolution=(w, h), settings=wb.RenderSettings(
            method="accumulation", samples=samples, threads=threads, aovs=(),
            shutter=(0.0, 0.0) if name == "sharp" else None))
        t, res = timed_median(lambda: renderer.render(args.frame), args.repeats)
        st = res.stats
        rows.append({"case": name, "samples": samples, "threads": threads, "seconds": t,
                     "per_instant_ms": 1000 * t / samples, "triangles": st["triangles"],
                     "tri_instants_per_s": st["triangles"] * samples / t,
                     **{f"t_{k}": v for k, v in st["time"].items() if k != "total"}})
    for name in ("sharp", "accumulation"):
        one = next(r for r in rows if r["case"] == name and r["threads"] == 1)
        many = next(r for r in rows if r["case"] == name and r["threads"] == cores)
        many["speedup_vs_1_thread"] = one["seconds"] / many["seconds"]
    cols = ["case", "samples", "threads", "seconds", "per_instant_ms", "tri_instants_per_s", "t_scene",
            "t_binning", "t_render", "speedup_vs_1_thread"]
    print(f"demo.usda frame {args.frame:g} at {w}x{h}, {cores} cores")
    print(table(rows, cols))
    print("saved", save("foundation.json", rows))


if __name__ == "__main__":
    main()

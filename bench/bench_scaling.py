"""Scaling: time and peak memory of each method against triangle count, resolution, motion length
(pixels) and depth complexity, on synthetic stages written here. Each case runs in a fresh process
so its peak resident memory (from the OS) is its own.

    python bench/bench_scaling.py --quick   # minutes
    python bench/bench_scaling.py           # 1k..256k triangles, 256²..1024²
    python bench/bench_scaling.py --full    # adds 1M triangles and 2048²
Writes bench/out/scaling.{json,png} and prints a table.
"""

from __future__ import annotations

import argparse
import json
import os
import subprocess
import sys

import numpy as np
from tqdm import tqdm

HERE = os.path.dirname(os.path.abspath(__file__))
sys.path.insert(0, HERE)
sys.path.insert(0, os.path.join(os.path.dirname(HERE), "stages"))
from common import OUT, pyplot, save, table  # noqa: E402

METHOD_SETTINGS = {"analytic": {}, "stochastic": {"samples": 16}, "accumulation": {"samples": 16},
                   "velocity": {}}


def make_scene(path: str, triangles: int, motion_px: float, layers: int, res_w: int) -> None:
    """A camera at z=10 looking at `triangles` small triangles spread over the view in `layers`
    depth layers, all translating so that the nearest layer moves `motion_px` pixels."""
    from authoring import add_camera, add_dome, add_distant_light, add_material, add_mesh, new_stage
    stage = new_stage(path)
    add_camera(stage)
    add_dome(stage)
    add_distant_light(stage, "/World/Sun", intensity=2.0)
    mat = add_material(stage, "/World/Looks/M", diffuse=(0.6, 0.4, 0.3), roughness=0.5, specular=(0.04,) * 3)
    rng = np.random.default_rng(1)
    per_layer = max(1, triangles // layers)
    units = motion_px * 10.0 / res_w  # window is 10 units wide at depth 10
    for layer in range(layers):
        z = -0.05 * layer
        side = int(np.ceil(np.sqrt(per_layer / 2)))
        xs, ys = np.meshgrid(np.linspace(-4.5, 4.5, side + 1), np.linspace(-3.4, 3.4, side + 1))
        pts = np.stack([xs.ravel(), ys.ravel(), np.full(xs.size, z)], 1) + rng.normal(0, 0.01, (xs.size, 3))
        idx = []
        for j in range(side):
            for i in range(side):
                a = j * (side + 1) + i
                idx += [a, a + 1, a + side + 2, a, a + side + 2, a + side + 1]
        idx = idx[: 3 * per_layer]
        add_mesh(stage, f"/World/L{layer}", pts.tolist(), [3] * (len(idx) // 3), idx, material=mat,
                 translate_samples={0.5: (-units / 2, 0, 0), 1.5: (units / 2, 0, 0)} if units else None,
                 translate=None if units else (0, 0, 0))
    stage.GetRootLayer().Save()


CHILD = r"""
import json, statistics, sys, time
import warp_blur as wb
scene, method, w, h, settings = sys.argv[1], sys.argv[2], int(sys.argv[3]), int(sys.argv[4]), json.loads(sys.argv[5])
r = wb.Renderer(scene, resolution=(w, h), settings=wb.RenderSettings(method=method, aovs=(), **settings))
res = r.render(1.0)
times = []
for _ in range(2):
    t0 = time.perf_counter(); res = r.render(1.0); times.append(time.perf_counter() - t0)
print(json.dumps({"seconds": statistics.median(times), "triangles": res.stats["triangles"],
                  "intervals_per_pixel": res.stats.get("intervals_per_pixel_mean")}))
"""


def run_case(scene: str, method: str, res: tuple[int, int]) -> dict:
    proc = subprocess.Popen([sys.executable, "-c", CHILD, scene, method, str(res[0]), str(res[1]),
                             json.dumps(METHOD_SETTINGS[method])], stdout=subprocess.PIPE, stderr=subprocess.PIPE)
    out = proc.stdout.read()
    proc.stderr.read()
    _, status, usage = os.wait4(proc.pid, 0)
    if status != 0:
        return {"seconds": float("nan"), "peak_mib": float("nan"), "error": True}
    data = json.loads(out.decode().strip().splitlines()[-1])
    data["peak_mib"] = usage.ru_maxrss / 1024.0
    return data


def main() -> None:
    ap = argparse.ArgumentParser()
    ap.add_argument("--quick", action="store_true")
    ap.add_argument("--full", action="store_true")
    ap.add_argument("--methods", default=",".join(METHOD_SETTINGS))
    args = ap.parse_args()
    methods = args.methods.split(",")
    if args.quick:
        tri_counts, resolutions, motions, layers = [1000, 16000, 64000], [256, 512], [0, 50, 200], [1, 16]
    else:
        tri_counts = [1000, 4000, 16000, 64000, 256000] + ([1000000] if args.full else [])
        resolutions = [256, 512, 1024] + ([2048] if args.full else [])
        motions, layers = [0, 10, 50, 100, 200], [1, 4, 16, 64]
    base_res = (512, 384)
    cases = ([("triangles", t, dict(triangles=t, motion_px=50, layers=1), base_res) for t in tri_counts]
             + [("resolution", r, dict(triangles=16000, motion_px=50 * r / 512, layers=1), (r, r)) for r in resolutions]
             + [("motion_px", m, dict(triangles=16000, motion_px=m, layers=1), base_res) for m in motions]
             + [("depth_layers", n, dict(triangles=16000, motion_px=50, layers=n), base_res) for n in layers])
    folder = os.path.join(OUT, "scenes")
    os.makedirs(folder, exist_ok=True)
    rows = []
    for axis, value, params, res in tqdm(cases, desc="scaling", unit="case"):
        scene = os.path.join(folder, f"scale_{params['triangles']}_{params['motion_px']:g}_{params['layers']}_{res[0]}.usda")
        if not os.path.exists(scene):
            make_scene(scene, res_w=res[0], **params)
        for m in methods:
            rows.append({"axis": axis, "value": value, "method": m, "resolution": f"{res[0]}x{res[1]}",
                         **run_case(scene, m, res)})
    print(table(rows, ["axis", "value", "method", "resolution", "seconds", "peak_mib", "intervals_per_pixel", "triangles"]))
    print("saved", save("scaling.json", rows))
    _plot(rows, methods, os.path.join(OUT, "scaling.png"))


def _plot(rows, methods, path):
    plt = pyplot()
    if plt is None:
        return
    axes_names = ["triangles", "resolution", "motion_px", "depth_layers"]
    fig, axes = plt.subplots(2, 4, figsize=(16, 7))
    for col, axis in enumerate(axes_names):
        for m in methods:
            pts = sorted((r["value"], r["seconds"], r["peak_mib"]) for r in rows if r["axis"] == axis and r["method"] == m)
            if pts:
                v, t, mem = zip(*pts)
                axes[0][col].plot(v, t, marker="o", label=m)
                axes[1][col].plot(v, mem, marker="o", label=m)
        axes[0][col].set_title(axis)
        axes[0][col].set_ylabel("seconds")
        axes[1][col].set_ylabel("peak MiB")
        for ax in (axes[0][col], axes[1][col]):
            ax.set_xlabel(axis)
            if axis in ("triangles", "resolution"):
                ax.set_xscale("log")
            ax.grid(True, alpha=0.3)
    axes[0][0].legend()
    fig.tight_layout()
    fig.savefig(path, dpi=100)


if __name__ == "__main__":
    main()

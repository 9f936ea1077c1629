"""Blender Cycles as a peer: time vs error of Cycles (CPU, motion blur) beside warp_blur's four
methods, in one run, against the same accumulation reference. Issue 18's targets are analytic's
leads over stochastic, accumulation and Cycles; velocity (an approximation, whose error stays
near its one sharp instant's) is timed and plotted beside them without a target.

    python bench/bench_peers.py --python /path/to/venv-with-bpy/bin/python   # pip install 'bpy==4.5.*'
    python bench/bench_peers.py --quick                                      # smaller images, fewer points

bpy is ~1 GB and needs Python 3.11: install it in a separate venv and pass its python (or set
WARP_BLUR_BPY_PYTHON); without it the bench says so and exits 0. Never run in CI.

So that the error measures blur and not shading models, every renderer renders an *emissive variant*
of each scene (bench/out/peers/<scene>_emissive.usda, flattened; bench/peer_variants.py lists what
it changes: emissive materials, no lights but the dome, Cubes as meshes, control cages, instancer
velocities baked into shutter-open/close samples). Conversions for Cycles
(bench/cycles_worker.py): Blender's USD importer (camera and meshes); each material an Emission
shader of the importer's emission colour; the dome's radiance as a constant world; shutter length 1
frame centred on the frame (the stages' (-0.5, 0.5)); Gaussian pixel filter 0.01 px (the pixel
centre, as SPEC §1; Blender syncs a box filter at 1 px whatever its width); no denoising, no
adaptive sampling, no bounces; transparent film, the dome colour added back as rgb + (1 - alpha) ×
dome. Times: warp_blur's Renderer.render (loading the frame included); Cycles' bpy.ops.render.render
(scene sync and BVH included; Blender start-up and the USD import excluded). A scene where Cycles at
its most samples stays above MISMATCH_RMSE from the reference is reported as a conversion mismatch
(e.g. motion the importer does not carry) and left out of the targets.
"""

from __future__ import annotations

import argparse
import json
import math
import os
import subprocess
import sys

from tqdm import tqdm

sys.path.insert(0, os.path.dirname(__file__))
from bench_tradeoff import SPEEDUP_TARGETS, TARGETS, target_verdicts, time_to_error  # noqa: E402
from common import OUT, ROOT, SCENES, pyplot, table, timed_rounds  # noqa: E402
from peer_variants import emissive_variant  # noqa: E402
from references import reference  # noqa: E402

import numpy as np  # noqa: E402

import warp_blur as wb  # noqa: E402
from warp_blur.output.files import read_exr  # noqa: E402
from warp_blur.output.metrics import rmse  # noqa: E402

SCENE_LIST = [("deep_overlap", 2, (512, 384)), ("rotation", 2, (640, 480)), ("large", 2, (1024, 768))]
MISMATCH_RMSE = 0.01
#: the curves of a scene, in the tables' and the plot's order
CURVES = ("analytic", "stochastic", "accumulation", "velocity", "cycles")


def ours_sweeps(quick: bool) -> dict[str, list[dict]]:
    """warp_blur's configurations per method: analytic's cheapest point (the draft at 32 time
    bits, as in bench_tradeoff's sweep), its presets and exact mode; the others' sample counts."""
    return {"analytic": [{"quality": "draft", "time_bits": 32}]
            + [{"quality": q} for q in ("draft", "preview", "final")] + [{"time_bits": 0}],
            "stochastic": [{"samples": n} for n in (16, 64, 256)],
            "accumulation": [{"samples": n} for n in (16, 64, 256)],
            "velocity": [{"samples": n} for n in ((4, 8, 16) if quick else (4, 8, 16, 32))]}


def scene_summary(name: str, scene_rows: list[dict]) -> list[dict]:
    """Per target RMSE: each curve's time to reach it (t_<method>), analytic's lead over each
    other curve (x_<method>) and issue 18's verdicts on the rivals it names (SPEEDUP_TARGETS:
    stochastic, accumulation, Cycles). Cycles rows noted as a conversion mismatch are left out."""
    curves = {m: [(r["seconds"], r["rmse"]) for r in scene_rows
                  if r["method"] == m and r.get("note") != "conversion mismatch"] for m in CURVES}
    curves = {m: pts for m, pts in curves.items() if pts}
    out = []
    for target in TARGETS:
        entry = {"scene": name, "target_rmse": target}
        for m, pts in curves.items():
            entry[f"t_{m}"] = time_to_error(pts, target)
        t_a = entry.get("t_analytic", math.inf)
        for m in curves:
            if m != "analytic":
                entry[f"x_{m}"] = entry[f"t_{m}"] / t_a if t_a < math.inf else math.nan
        entry["targets"] = target_verdicts(entry, [m for m in curves if m in SPEEDUP_TARGETS])
        out.append(entry)
    return out


def bpy_python(explicit: str | None) -> str | None:
    """A Python that can import bpy (explicit, $WARP_BLUR_BPY_PYTHON, or this one), else None."""
    for cand in (explicit, os.environ.get("WARP_BLUR_BPY_PYTHON"), sys.executable):
        try:
            if cand and subprocess.run([cand, "-c", "import bpy"], capture_output=True).returncode == 0:
                return cand
        except OSError:   # not an executable (a mistyped --python): try the next
            continue
    return None


def cycles_points(python: str, scene: str, frame: int, res: tuple[int, int], dome, spp: list[int], out_dir: str,
                  ref: np.ndarray) -> list[dict]:
    """Render with Cycles at each spp (one Blender process); rows of seconds and error."""
    cmd = [python, os.path.join(ROOT, "bench", "cycles_worker.py"), scene, "--frame", str(frame),
           "--resolution", f"{res[0]}x{res[1]}", "--dome", ",".join(f"{v:g}" for v in dome),
           "--spp", ",".join(map(str, spp)), "--threads", str(os.cpu_count() or 1), "--out", out_dir]
    proc = subprocess.run(cmd, capture_output=True, text=True)
    if proc.returncode != 0:
        raise RuntimeError(f"cycles_worker failed: {proc.stderr.strip().splitlines()[-1:]}")
    rows = []
    for line in proc.stdout.splitlines():
        if line.startswith("{"):
            r = json.loads(line)
            img = read_exr(r["exr"])["RGBA"].astype(np.float32).copy()
            img[..., :3] += (1.0 - img[..., 3:4]) * np.asarray(dome, np.float32)
            rows.append({"method": "cycles", "knob": f"{r['spp']} spp", "seconds": r["seconds"], "rmse": rmse(img, ref)})
    return rows


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--python", help="a Python with bpy installed (else $WARP_BLUR_BPY_PYTHON, else this one)")
    ap.add_argument("--scenes", default=",".join(s[0] for s in SCENE_LIST))
    ap.add_argument("--quick", action="store_true")
    ap.add_argument("--repeats", type=int, help="timed rounds of every configuration (3; 1 with --quick), as "
                    "bench_tradeoff.py")
    ap.add_argument("--ref-samples", type=int, help="reference instants (default 4096; 1024 with --quick)")
    args = ap.parse_args()
    python = bpy_python(args.python)
    if python is None:
        print("bench_peers: skipped — no Python here can import bpy (pip install 'bpy==4.5.*' in a Python 3.11 "
              "venv and pass --python that/venv/bin/python)")
        return
    chosen = [s for s in SCENE_LIST if s[0] in args.scenes.split(",")]
    args.repeats = args.repeats or (1 if args.quick else 3)
    ours = ours_sweeps(args.quick)
    spp = [16, 64, 256] if args.quick else [16, 64, 256, 1024]
    ref_n = args.ref_samples or (1024 if args.quick else 4096)
    peers_dir = os.path.join(OUT, "peers")
    os.makedirs(peers_dir, exist_ok=True)
    rows, summary = [], []
    bar = tqdm(total=len(chosen) * (2 + sum(len(k) for k in ours.values()) + args.repeats), desc="peers", unit="run")
    for name, frame, res in chosen:
        if args.quick:
            res = (res[0] // 2, res[1] // 2)
        variant = os.path.join(peers_dir, f"{name}_emissive.usda")
        dome = emissive_variant(os.path.join(SCENES, f"{name}.usda"), variant, frame)
        bar.set_postfix_str(f"{name} reference ({ref_n})")
        ref = reference(variant, frame, res, ref_n)
        bar.update(1)
        scene_rows = []
        configs = [(method, knob, wb.Renderer(variant, resolution=res,
                                              settings=wb.RenderSettings(method=method, aovs=(), **knob)))
                   for method, knobs in ours.items() for knob in knobs]
        bar.set_postfix_str(f"{name}: {len(configs)} configurations, then {args.repeats} rounds of all")
        # each round renders every configuration in turn (common.timed_rounds)
        timed = timed_rounds([lambda r=renderer: r.render(frame) for _m, _k, renderer in configs], args.repeats,
                             progress=lambda: bar.update(1))
        for (method, knob, _r), (seconds, result) in zip(configs, timed):
            scene_rows.append({"method": method, "knob": json.dumps(knob), "seconds": seconds,
                               "rmse": rmse(result.rgba, ref)})
        del configs, timed
        bar.set_postfix_str(f"{name} cycles {spp}")
        cyc = cycles_points(python, variant, frame, res, dome, spp, os.path.join(peers_dir, name), ref)
        bar.update(1)
        mismatch = min(r["rmse"] for r in cyc) > MISMATCH_RMSE
        for r in cyc:
            r["note"] = "conversion mismatch" if mismatch else ""
        scene_rows += cyc
        for r in scene_rows:
            r["scene"] = name
        rows += scene_rows
        summary += scene_summary(name, scene_rows)
    bar.close()
    with open(os.path.join(OUT, "peers.json"), "w") as f:
        json.dump({"runs": rows, "time_to_error": summary, "quick": args.quick, "python": python}, f,
                  indent=2, default=str)
    print(table(rows, ["scene", "method", "knob", "seconds", "rmse", "note"]))
    print()
    cols = ["scene", "target_rmse"] + [f"t_{m}" for m in CURVES]
    cols += [f"x_{m}" for m in CURVES if m != "analytic"] + ["targets"]
    print(table(summary, cols))
    _plot(rows, [c[0] for c in chosen], os.path.join(OUT, "peers.png"))
    print("wrote", os.path.join(OUT, "peers.json"), "peers.png")


def _plot(rows: list[dict], scenes: list[str], path: str) -> None:
    plt = pyplot()
    if plt is None:
        return
    fig, axes = plt.subplots(1, len(scenes), figsize=(4.4 * len(scenes), 3.8), squeeze=False)
    for ax, name in zip(axes[0], scenes):
        for m in CURVES:
            pts = sorted((r["seconds"], r["rmse"]) for r in rows if r["scene"] == name and r["method"] == m)
            if pts:
                ax.loglog(*zip(*pts), marker="o", label=m)
        ax.set_title(f"{name} (emissive)")
        ax.set_xlabel("seconds per frame")
        ax.set_ylabel("RMSE vs accumulation reference")
        ax.grid(True, which="both", alpha=0.3)
    axes[0][0].legend()
    fig.tight_layout()
    fig.savefig(path, dpi=110)


if __name__ == "__main__":
    main()

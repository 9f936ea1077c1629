"""A field of particle spheres (a point instancer of implicit spheres receding from the camera,
half of them drifting, under a sun and a dome): what a frame costs with each sphere tessellated
for its size on screen (usd/tessellate.sphere_levels) at the draft's bound (0.1 px) and the
default's (0.025 px) against every sphere at the full 1280 triangles, for every method, in one
run; and, for analytic, how far each is from a finer tessellation (level 4, 5120 triangles,
everywhere) as RMSE over 4x4-pixel boxes (a pixel centre near a sub-pixel sphere's silhouette
flips with any change of its facets; the boxes weigh what is covered).

    python bench/bench_particles.py [--spheres 1000] [--resolution 640x480] [--frames 2] [--no-accuracy]
"""

from __future__ import annotations

import argparse
import contextlib
import os
import sys

import numpy as np

sys.path.insert(0, os.path.dirname(__file__))
sys.path.insert(0, os.path.join(os.path.dirname(os.path.dirname(os.path.abspath(__file__))), "stages"))
from authoring import sphere_field  # noqa: E402
from common import METHODS, OUT, median_frame_seconds, save, table  # noqa: E402

import warp_blur as wb  # noqa: E402
from warp_blur.output.metrics import rmse  # noqa: E402
from warp_blur.usd import instancer, tessellate  # noqa: E402


@contextlib.contextmanager
def every_sphere_at(level: int | None):
    """Within: every instanced sphere at `level` (None: levels for size on screen), reduced levels
    unscaled when `level` is above the full level (the finer reference)."""
    keep = instancer.sphere_levels, instancer.SPHERE_LEVEL_MAX, tessellate.SPHERE_LEVEL_MAX
    if level is not None:
        instancer.sphere_levels = lambda r, *_: np.full(np.shape(r), level, np.int64)
        instancer.SPHERE_LEVEL_MAX = tessellate.SPHERE_LEVEL_MAX = max(level, keep[2])
    tessellate._trimesh_shape.cache_clear()
    try:
        yield
    finally:
        instancer.sphere_levels, instancer.SPHERE_LEVEL_MAX, tessellate.SPHERE_LEVEL_MAX = keep
        tessellate._trimesh_shape.cache_clear()


#: the tessellations compared: (column, every sphere at this level or None, sphere_error_px)
VARIANTS = [("0.1 px s", None, 0.1), ("0.025 px s", None, 0.025), ("full s", 3, None)]


def frame_seconds(path: str, res: tuple[int, int], method: str, frames: list[float], level: int | None,
                  error_px: float | None) -> float:
    """Median seconds a frame over `frames` (after a warm-up frame) on one Renderer."""
    with every_sphere_at(level):
        r = wb.Renderer(path, resolution=res,
                        settings=wb.RenderSettings(method=method, aovs=(), sphere_error_px=error_px))
        return median_frame_seconds(r.render, frames)


def box_filtered(rgba: np.ndarray, k: int = 4) -> np.ndarray:
    h, w = rgba.shape[0] // k * k, rgba.shape[1] // k * k
    return rgba[:h, :w].reshape(h // k, k, w // k, k, -1).mean(axis=(1, 3))


def accuracy(path: str, res: tuple[int, int], frame: float) -> list[dict]:
    """Analytic's triangles and RMSE (4x4 boxes) against level 4 everywhere, per tessellation."""
    from tqdm import tqdm
    images = {}
    for name, level, error_px in tqdm([("level 4 (reference)", 4, None), ("level 3 everywhere", 3, None),
                                       ("0.0125 px (final)", None, 0.0125), ("0.025 px (default)", None, 0.025),
                                       ("0.05 px (preview)", None, 0.05), ("0.1 px (draft)", None, 0.1)],
                                      desc="accuracy", unit="render"):
        with every_sphere_at(level):
            r = wb.render(path, frame=frame, method="analytic", resolution=res, aovs=(), sphere_error_px=error_px)
        images[name] = (box_filtered(r.rgba), r.stats["triangles"])
    ref = images["level 4 (reference)"][0]
    return [{"tessellation": k, "triangles": n, "rmse vs level 4": rmse(img, ref)} for k, (img, n) in images.items()]


def main() -> None:
    ap = argparse.ArgumentParser()
    ap.add_argument("--spheres", type=int, default=1000)
    ap.add_argument("--resolution", default="640x480")
    ap.add_argument("--frames", type=int, default=2, help="frames timed after a warm-up frame")
    ap.add_argument("--no-accuracy", action="store_true", help="skip the level-4 comparison")
    args = ap.parse_args()
    res = tuple(int(v) for v in args.resolution.split("x"))
    os.makedirs(os.path.join(OUT, "scenes"), exist_ok=True)
    path = sphere_field(os.path.join(OUT, "scenes", f"particles_{args.spheres}.usda"), args.spheres)
    frames = [float(f) for f in range(5, 5 + args.frames)]
    from tqdm import tqdm
    rows = []
    with tqdm(total=len(METHODS) * len(VARIANTS), desc="particles", unit="run") as bar:
        for method in METHODS:
            row = {"method": method}
            for column, level, error_px in VARIANTS:
                row[column] = frame_seconds(path, res, method, frames, level, error_px)
                bar.update()
            row["full / 0.025"] = row["full s"] / row["0.025 px s"]
            row["full / 0.1"] = row["full s"] / row["0.1 px s"]
            rows.append(row)
    print(f"\n{args.spheres} particle spheres at {res[0]}x{res[1]}, median of {args.frames} frames a row")
    print(table(rows, ["method"] + [v[0] for v in VARIANTS] + ["full / 0.025", "full / 0.1"]))
    acc = [] if args.no_accuracy else accuracy(path, res, frames[0])
    if acc:
        print(f"\nanalytic, frame {frames[0]:g}: RMSE over 4x4-pixel boxes against every sphere at level 4")
        print(table(acc, ["tessellation", "triangles", "rmse vs level 4"]))
    print("saved", save("particles.json", {"spheres": args.spheres, "resolution": res, "rows": rows,
                                           "accuracy": acc}))


if __name__ == "__main__":
    main()

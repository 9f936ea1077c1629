"""Images before and after a change that must not change them (a package move): renders every
shipped stage with every method at a small size and saves the pixels; `--compare A B` says
whether two such files are bit-identical.

    python bench/image_identity.py --save bench/out/before.npz
    python bench/image_identity.py --save bench/out/after.npz --compare bench/out/before.npz
"""

from __future__ import annotations

import argparse
import os
import sys

import numpy as np

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
STAGES = ["crossing", "demo", "large", "near_plane", "rotation", "shadows", "skinned"]
METHODS = ["accumulation", "stochastic", "analytic", "velocity"]


def render_all() -> dict[str, np.ndarray]:
    """{'stage/method': (H, W, 4) float32} at 64x48 with few samples (shadows on, the default)."""
    import warp_blur as wb
    from tqdm import tqdm
    out = {}
    for stage in tqdm(STAGES, unit="stage"):
        renderer = None
        for method in METHODS:
            renderer = wb.Renderer(os.path.join(ROOT, "usd_scenes", f"{stage}.usda"), resolution=(64, 48),
                                   settings=wb.RenderSettings(method=method, samples=4, shadow_map_size=128,
                                                              aovs=("Z", "motion")))
            res = renderer.render(renderer.default_frame() + 1)
            out[f"{stage}/{method}"] = res.rgba
            out[f"{stage}/{method}/Z"] = res.aovs["Z"]
            out[f"{stage}/{method}/motion"] = res.aovs["motion"]
    return out


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--save", required=True, help="where to write this run's pixels (.npz)")
    ap.add_argument("--compare", help="an earlier run's .npz: exit 1 unless every image is bit-identical")
    a = ap.parse_args()
    images = render_all()
    os.makedirs(os.path.dirname(os.path.abspath(a.save)), exist_ok=True)
    np.savez_compressed(a.save, **images)
    if not a.compare:
        return 0
    before = np.load(a.compare)
    differ = [k for k in images if k not in before or not np.array_equal(before[k], images[k], equal_nan=True)]
    print(f"{len(images) - len(differ)} of {len(images)} images bit-identical" + (f"; differ: {differ}" if differ else ""))
    return 1 if differ else 0


if __name__ == "__main__":
    sys.exit(main())

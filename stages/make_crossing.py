"""Write usd_scenes/crossing.usda: 16 emissive layers over the same pixels whose depth order
reverses during the shutter (every pair crosses in depth-time), over a dome."""

from __future__ import annotations

import colorsys
import os
import sys

sys.path.insert(0, os.path.dirname(__file__))
from authoring import add_camera, add_dome, add_material, add_quad, new_stage  # noqa: E402

OUT = os.path.join(os.path.dirname(__file__), "..", "usd_scenes", "crossing.usda")


def main(path: str = OUT, layers: int = 16) -> str:
    stage = new_stage(path, start=1, end=3, doc="warp_blur crossing: 16 layers reversing depth order in one shutter.")
    add_camera(stage, translate=(0, 0, 10), shutter=(-0.5, 0.5))
    add_dome(stage)
    for i in range(layers):
        mat = add_material(stage, f"/World/Looks/L{i:02d}", emissive=colorsys.hsv_to_rgb(i / layers, 0.75, 0.95))
        dx = 0.25 * ((i % 5) - 2)
        add_quad(stage, f"/World/L{i:02d}", 1.6, 1.2, material=mat,
                 translate_samples={1.5: (-dx - 0.6, 0.08 * (i % 4) - 0.12, -0.05 * i),
                                    2.5: (dx + 0.6, 0.12 - 0.08 * (i % 4), -0.05 * (layers - 1 - i))})
    stage.GetRootLayer().Save()
    return path


if __name__ == "__main__":
    print(main(sys.argv[1] if len(sys.argv) > 1 else OUT))

"""Write usd_scenes/deep_overlap.usda: 48 emissive layers stacked over the same pixels, sliding,
turning and passing through one another within one shutter (tilted, so they interpenetrate), seen
by a camera that dollies sideways: the deep-overlap case where blur is expensive."""

from __future__ import annotations

import colorsys
import os
import sys

sys.path.insert(0, os.path.dirname(__file__))
from authoring import add_camera, add_dome, add_material, add_mesh, new_stage  # noqa: E402
from pxr import UsdGeom  # noqa: E402

OUT = os.path.join(os.path.dirname(__file__), "..", "usd_scenes", "deep_overlap.usda")


def main(path: str = OUT, layers: int = 48) -> str:
    stage = new_stage(path, start=1, end=3,
                      doc="warp_blur deep_overlap: 48 moving, turning, interpenetrating layers over one region.")
    add_camera(stage, translate_samples={1.5: (-0.3, 0, 10), 2.5: (0.3, 0, 10)}, shutter=(-0.5, 0.5))
    add_dome(stage)
    pts = [(-1.5, -1.1, 0.0), (1.5, -1.1, 0.0), (1.5, 1.1, 0.0), (-1.5, 1.1, 0.0)]
    for i in range(layers):
        mat = add_material(stage, f"/World/Looks/L{i:02d}", emissive=colorsys.hsv_to_rgb(i / layers, 0.7, 0.9))
        dx = 0.2 * ((i % 7) - 3)
        dy = 0.1 * ((i % 5) - 2)
        # the depth order is shuffled over the shutter (19 is prime to 48: a permutation), so pairs
        # cross at many different times, never all at once
        z0, z1 = -0.04 * i, -0.04 * ((19 * i + 7) % layers)
        mesh = add_mesh(stage, f"/World/L{i:02d}", pts, [4], [0, 1, 2, 3], material=mat)
        mesh.AddTranslateOp().GetAttr().Set((-dx - 0.5, dy, z0), 1.5)
        mesh.GetOrderedXformOps()[0].GetAttr().Set((dx + 0.5, -dy, z1), 2.5)
        spin = mesh.AddRotateZOp()
        spin.Set(0.0, 1.5)
        spin.Set(40.0 * (1 if i % 2 else -1) * (1 + (i % 3)) / 3.0, 2.5)
        mesh.AddRotateYOp().Set(8.0 * ((i % 5) - 2))   # tilted: neighbours interpenetrate along lines
    UsdGeom.SetStageMetersPerUnit(stage, 1.0)
    stage.GetRootLayer().Save()
    return path


if __name__ == "__main__":
    print(main(sys.argv[1] if len(sys.argv) > 1 else OUT))

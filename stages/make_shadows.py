"""Write usd_scenes/shadows.usda: shadows in motion (issue 6).

Over a static lit ground: a box translating fast (its shadow blurs), a slab spinning (its shadow
sweeps), and a post that stands still (its shadow stays sharp, except where the moving lamp
sweeps it). A static sun (distant light) and a rect lamp that moves across the shutter, both
casting shadows. The camera is still. Shutter [-0.5, 0.5]; frames 1:12.
"""

from __future__ import annotations

import os
import sys

sys.path.insert(0, os.path.dirname(__file__))
from authoring import add_camera, add_distant_light, add_material, add_mesh, add_xform_ops, bind, grid, new_stage  # noqa: E402
from pxr import Gf, UsdGeom, UsdLux  # noqa: E402

OUT = os.path.join(os.path.dirname(__file__), "..", "usd_scenes", "shadows.usda")


def main(path: str = OUT) -> str:
    stage = new_stage(path, start=1, end=12, doc="warp_blur shadows: moving occluders over a static ground, "
                      "a static sun and a moving rect lamp; render frames 1:12.")
    add_camera(stage, translate=(0.0, 5.5, 9.0), rotate_axis="X", rotate_samples={1: -30.0}, shutter=(-0.5, 0.5))
    add_distant_light(stage, "/World/Sun", intensity=2.0, color=(1.0, 0.96, 0.9), rotate=(-60, 25, 0))
    lamp = UsdLux.RectLight.Define(stage, "/World/Lamp")
    lamp.CreateWidthAttr(1.0)
    lamp.CreateHeightAttr(1.0)
    lamp.CreateIntensityAttr(12.0)
    lamp.CreateColorAttr(Gf.Vec3f(0.9, 0.8, 1.0))
    UsdLux.ShadowAPI.Apply(lamp.GetPrim()).CreateShadowEnableAttr(True)
    # the lamp faces down (-Z of a rect light rotated -90° about X) and moves along x
    add_xform_ops(lamp, translate_samples={1: (-3.0, 4.0, 1.0), 12: (3.0, 4.0, 1.0)}, rotate_axis="X", rotate=-90.0)
    ground = add_material(stage, "/World/Looks/Ground", diffuse=(0.6, 0.6, 0.58), roughness=0.9)
    red = add_material(stage, "/World/Looks/Red", diffuse=(0.7, 0.15, 0.1), roughness=0.5)
    teal = add_material(stage, "/World/Looks/Teal", diffuse=(0.1, 0.55, 0.5), roughness=0.6)
    grey = add_material(stage, "/World/Looks/Grey", diffuse=(0.4, 0.4, 0.42), roughness=0.7)
    pts, counts, idx = grid(6, 6, 14.0, 14.0)
    add_mesh(stage, "/World/Ground", [(x, 0.0, -y) for x, y, _ in pts], counts, idx, material=ground)

    box = UsdGeom.Cube.Define(stage, "/World/Box")
    box.CreateSizeAttr(1.0)
    add_xform_ops(box, translate_samples={1: (-5.0, 1.2, 0.5), 12: (5.0, 1.2, 0.5)})
    bind(box.GetPrim(), red)

    slab = UsdGeom.Cube.Define(stage, "/World/Slab")
    slab.CreateSizeAttr(1.0)
    add_xform_ops(slab, translate=(1.5, 1.6, -2.0), rotate_axis="Y", rotate_samples={1: 0.0, 12: 330.0},
                  scale=(2.4, 0.15, 0.6))
    bind(slab.GetPrim(), teal)

    post = UsdGeom.Cylinder.Define(stage, "/World/Post")
    post.CreateRadiusAttr(0.25)
    post.CreateHeightAttr(2.0)
    add_xform_ops(post, translate=(-2.0, 1.0, -1.5))
    bind(post.GetPrim(), grey)
    stage.GetRootLayer().Save()
    return path


if __name__ == "__main__":
    print(main(sys.argv[1] if len(sys.argv) > 1 else OUT))

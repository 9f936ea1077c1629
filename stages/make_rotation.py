"""Write usd_scenes/rotation.usda: a propeller turning 180 degrees about the view axis and a lit box
tumbling 90 degrees about a tilted axis within one shutter (rotations are arcs)."""

from __future__ import annotations

import os
import sys

sys.path.insert(0, os.path.dirname(__file__))
from authoring import add_camera, add_distant_light, add_dome, add_material, add_mesh, add_xform_ops, bind, new_stage  # noqa: E402
from pxr import UsdGeom  # noqa: E402

OUT = os.path.join(os.path.dirname(__file__), "..", "usd_scenes", "rotation.usda")


def main(path: str = OUT) -> str:
    stage = new_stage(path, start=1, end=3, doc="warp_blur rotation: 180 and 90 degree turns within the shutter.")
    add_camera(stage, translate=(0, 0, 10), shutter=(-0.5, 0.5))
    add_dome(stage, color=(0.06, 0.07, 0.1))
    add_distant_light(stage, "/World/Sun", intensity=2.5, rotate=(-30, 40, 0))
    blade = add_material(stage, "/World/Looks/Blade", emissive=(0.95, 0.8, 0.3))
    red = add_material(stage, "/World/Looks/Red", diffuse=(0.7, 0.15, 0.1), roughness=0.4, specular=(0.06,) * 3)
    pts = [(0.0, -0.15, 0), (2.2, -0.3, 0), (2.2, 0.3, 0), (0.0, 0.15, 0),
           (-2.2, 0.3, 0), (-2.2, -0.3, 0)]
    add_mesh(stage, "/World/Propeller", pts, [4, 4], [0, 1, 2, 3, 3, 4, 5, 0], material=blade,
             translate=(-1.6, 0.4, 0), rotate_axis="Z", rotate_samples={1.5: 0.0, 2.5: 180.0})
    box = UsdGeom.Cube.Define(stage, "/World/Box")
    box.CreateSizeAttr(1.4)
    add_xform_ops(box, translate=(2.2, -0.3, 0), rotate_axis="X", rotate_samples={1.5: -45.0, 2.5: 45.0})
    bind(box.GetPrim(), red)
    stage.GetRootLayer().Save()
    return path


if __name__ == "__main__":
    print(main(sys.argv[1] if len(sys.argv) > 1 else OUT))

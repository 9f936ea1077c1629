"""Write usd_scenes/near_plane.usda: a lit wall rushing through the camera's near plane during the
shutter, and a quad passing close beside the eye, over a lit ground."""

from __future__ import annotations

import os
import sys

sys.path.insert(0, os.path.dirname(__file__))
from authoring import add_camera, add_distant_light, add_dome, add_material, add_mesh, add_quad, grid, new_stage  # noqa: E402

OUT = os.path.join(os.path.dirname(__file__), "..", "usd_scenes", "near_plane.usda")


def main(path: str = OUT) -> str:
    stage = new_stage(path, start=1, end=3, doc="warp_blur near_plane: geometry crossing the near plane mid-shutter.")
    add_camera(stage, translate=(0, 1.5, 10), clipping=(0.5, 200), shutter=(-0.5, 0.5))
    add_dome(stage, color=(0.05, 0.06, 0.09))
    add_distant_light(stage, "/World/Sun", intensity=2.0, rotate=(-40, 25, 0))
    grey = add_material(stage, "/World/Looks/Grey", diffuse=(0.5, 0.5, 0.5), roughness=0.7, specular=(0.04,) * 3)
    orange = add_material(stage, "/World/Looks/Orange", diffuse=(0.8, 0.4, 0.1), roughness=0.4, specular=(0.05,) * 3)
    glow = add_material(stage, "/World/Looks/Glow", emissive=(0.3, 0.9, 0.6))
    pts, c, i = grid(6, 6, 30.0, 30.0)
    add_mesh(stage, "/World/Ground", [(x, 0.0, -y) for x, y, _ in pts], c, i, material=grey)
    pts, c, i = grid(4, 3, 3.0, 2.0)
    add_mesh(stage, "/World/Wall", pts, c, i, material=orange,
             translate_samples={1.5: (0.4, 1.6, 6.0), 2.5: (0.4, 1.6, 11.5)})
    add_quad(stage, "/World/Passer", 0.6, 0.6, material=glow,
             translate_samples={1.5: (-1.2, 1.2, 4.0), 2.5: (-0.9, 1.3, 12.0)})
    stage.GetRootLayer().Save()
    return path


if __name__ == "__main__":
    print(main(sys.argv[1] if len(sys.argv) > 1 else OUT))

"""Write usd_scenes/demo.usda: the README's demo shot (24 frames).

A spinning cube, a sphere racing across, a waving flag (deforming mesh), a ring of instanced cones
(PointInstancer), all over a lit ground; the camera trucks and pans; a distant light, a moving
sphere light and a dim dome. Shutter [-0.25, 0.25] (180 degrees).
"""

from __future__ import annotations

import math
import os
import sys

sys.path.insert(0, os.path.dirname(__file__))
from authoring import (add_camera, add_dome, add_distant_light, add_material, add_mesh, add_sphere_light,  # noqa: E402
                       add_xform_ops, bind, grid, new_stage)
from pxr import Gf, UsdGeom, Vt  # noqa: E402

OUT = os.path.join(os.path.dirname(__file__), "..", "usd_scenes", "demo.usda")


def main(path: str = OUT) -> str:
    frames = list(range(1, 25))
    stage = new_stage(path, start=1, end=24, doc="warp_blur demo: translating, spinning, deforming and instanced "
                      "objects, a moving camera and lights; render frames 1:24.")
    add_camera(stage, translate_samples={1: (-1.0, 2.2, 11.0), 24: (1.5, 2.6, 9.5)},
               rotate_axis="Y", rotate_samples={1: -4.0, 24: 6.0}, shutter=(-0.25, 0.25))
    add_dome(stage, color=(0.08, 0.09, 0.12))
    add_distant_light(stage, "/World/Sun", intensity=2.5, color=(1.0, 0.95, 0.85), rotate=(-50, 35, 0))
    add_sphere_light(stage, "/World/Lamp", radius=0.25, intensity=30.0, color=(1.0, 0.6, 0.3),
                     translate_samples={1: (-4.0, 2.5, 3.0), 24: (4.0, 2.5, 3.0)})
    ground_mat = add_material(stage, "/World/Looks/Ground", diffuse=(0.45, 0.45, 0.42), roughness=0.8,
                              specular=(0.04, 0.04, 0.04))
    red = add_material(stage, "/World/Looks/Red", diffuse=(0.7, 0.12, 0.1), roughness=0.35,
                       specular=(0.08, 0.08, 0.08))
    blue = add_material(stage, "/World/Looks/Blue", diffuse=(0.1, 0.25, 0.75), roughness=0.2,
                        metallic=0.0, specular_workflow=False)
    glow = add_material(stage, "/World/Looks/Glow", emissive=(3.0, 2.4, 0.8))
    cloth = add_material(stage, "/World/Looks/Cloth", diffuse=(0.2, 0.6, 0.3), roughness=0.9)

    pts, counts, idx = grid(10, 10, 24.0, 24.0)
    ground = add_mesh(stage, "/World/Ground", [(x, 0.0, -y) for x, y, _ in pts], counts, idx, material=ground_mat)
    ground.GetPrim()

    cube = UsdGeom.Cube.Define(stage, "/World/SpinCube")
    cube.CreateSizeAttr(1.6)
    add_xform_ops(cube, translate=(-3.0, 1.2, 0.0), rotate_axis="Y",
                  rotate_samples={f: 25.0 * (f - 1) for f in (1, 24)})
    bind(cube.GetPrim(), red)

    ball = UsdGeom.Sphere.Define(stage, "/World/Ball")
    ball.CreateRadiusAttr(0.8)
    add_xform_ops(ball, translate_samples={1: (-7.0, 0.8, 2.5), 24: (7.0, 0.8, 2.5)})
    bind(ball.GetPrim(), blue)

    def wave(x, y, t):
        return 0.35 * math.sin(1.6 * x + 0.9 * t)
    flag_frames = {f: [(x + 3.2, y + 2.0, z - 1.5) for x, y, z in grid(8, 5, 2.4, 1.5, wave, f)[0]] for f in frames}
    _, fc, fi = grid(8, 5, 2.4, 1.5)
    add_mesh(stage, "/World/Flag", None, fc, fi, material=cloth, points_samples=flag_frames)

    inst = UsdGeom.PointInstancer.Define(stage, "/World/Ring")
    cone = UsdGeom.Cone.Define(stage, "/World/Ring/Prototypes/Cone")
    cone.CreateRadiusAttr(0.3)
    cone.CreateHeightAttr(0.8)
    bind(cone.GetPrim(), glow)
    inst.CreatePrototypesRel().SetTargets([cone.GetPath()])
    n = 6
    inst.CreateProtoIndicesAttr(Vt.IntArray([0] * n))
    pos_attr = inst.CreatePositionsAttr()
    for f in frames:
        a0 = 0.12 * (f - 1)
        pos_attr.Set(Vt.Vec3fArray([Gf.Vec3f(1.8 * math.cos(a0 + 2 * math.pi * k / n), 0.4,
                                             1.8 * math.sin(a0 + 2 * math.pi * k / n) + 4.0) for k in range(n)]), f)
    stage.GetRootLayer().Save()
    return path


if __name__ == "__main__":
    print(main(sys.argv[1] if len(sys.argv) > 1 else OUT))

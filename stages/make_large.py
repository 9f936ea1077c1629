"""Write usd_scenes/large.usda: about 70k triangles (the seed paper's scale) for benchmarks:
870 instanced 80-triangle rocks (a PointInstancer with velocities and angular velocities) over a
ground, with a distant light and a dome. Render at 1024x768.

USD applies angular velocities to authored orientations only, and this stage authors none, so
its rocks translate without turning (UsdGeom.PointInstancer.ComputeInstanceTransformsAtTime,
which the renderer uses, says the same). Kept as it is: every `large` figure in docs/ is of it."""

from __future__ import annotations

import os
import sys

import numpy as np
import trimesh

sys.path.insert(0, os.path.dirname(__file__))
from authoring import add_camera, add_distant_light, add_dome, add_material, add_mesh, bind, grid, new_stage  # noqa: E402
from pxr import Gf, UsdGeom, Vt  # noqa: E402

OUT = os.path.join(os.path.dirname(__file__), "..", "usd_scenes", "large.usda")


def main(path: str = OUT, count: int = 870, moving_fraction: float = 1.0, speed: float = 1.0) -> str:
    """moving_fraction < 1 keeps that share of the rocks moving and the rest still; speed scales the
    moving rocks' velocities and spins (bench variants)."""
    stage = new_stage(path, start=1, end=3, doc="warp_blur large: ~70k moving triangles for benchmarks (1024x768).")
    add_camera(stage, translate=(0, 6, 26), rotate_axis="X", rotate_samples={1: -12.0}, shutter=(-0.5, 0.5))
    add_dome(stage, color=(0.08, 0.09, 0.12))
    add_distant_light(stage, "/World/Sun", intensity=2.5, rotate=(-50, 30, 0))
    ground = add_material(stage, "/World/Looks/Ground", diffuse=(0.4, 0.4, 0.38), roughness=0.8)
    rock = add_material(stage, "/World/Looks/Rock", diffuse=(0.55, 0.35, 0.25), roughness=0.5, specular=(0.04,) * 3)
    pts, c, i = grid(8, 8, 60.0, 60.0)
    add_mesh(stage, "/World/Ground", [(x, 0.0, -y) for x, y, _ in pts], c, i, material=ground)
    ico = trimesh.creation.icosphere(subdivisions=1, radius=0.5)
    inst = UsdGeom.PointInstancer.Define(stage, "/World/Rocks")
    proto = add_mesh(stage, "/World/Rocks/Protos/Rock", [tuple(map(float, v)) for v in ico.vertices],
                     [3] * len(ico.faces), [int(x) for x in ico.faces.ravel()], material=rock)
    proto.CreateSubdivisionSchemeAttr(UsdGeom.Tokens.catmullClark)  # rendered as its cage, smooth normals
    bind(proto.GetPrim(), rock)
    inst.CreatePrototypesRel().SetTargets([proto.GetPath()])
    rng = np.random.default_rng(7)
    pos = np.stack([rng.uniform(-22, 22, count), rng.uniform(0.5, 9.0, count), rng.uniform(-30, 8, count)], 1)
    vel = np.stack([rng.normal(0, 20, count), rng.normal(0, 6, count), rng.normal(0, 6, count)], 1)
    ang = rng.normal(0, 400, (count, 3))
    still = np.arange(count) >= int(round(moving_fraction * count))
    vel[still] = 0.0
    ang[still] = 0.0
    vel *= speed
    ang *= speed
    inst.CreateProtoIndicesAttr(Vt.IntArray([0] * count))
    inst.CreatePositionsAttr().Set(Vt.Vec3fArray([Gf.Vec3f(*map(float, p)) for p in pos]), 2.0)
    inst.CreateVelocitiesAttr().Set(Vt.Vec3fArray([Gf.Vec3f(*map(float, v)) for v in vel]), 2.0)
    inst.CreateAngularVelocitiesAttr().Set(Vt.Vec3fArray([Gf.Vec3f(*map(float, a)) for a in ang]), 2.0)
    inst.CreateScalesAttr(Vt.Vec3fArray([Gf.Vec3f(*map(float, s)) for s in rng.uniform(0.5, 1.6, (count, 3))]))
    stage.GetRootLayer().Save()
    return path


if __name__ == "__main__":
    print(main(sys.argv[1] if len(sys.argv) > 1 else OUT))

"""Write usd_scenes/skinned.usda: a skinned arm (UsdSkel: two joints, linear blend skinning) whose
shoulder and elbow swing during the shutter, lit, over a ground (24 frames)."""

from __future__ import annotations

import math
import os
import sys

sys.path.insert(0, os.path.dirname(__file__))
from authoring import add_camera, add_distant_light, add_dome, add_material, add_mesh, bind, grid, new_stage  # noqa: E402
from pxr import Gf, UsdGeom, UsdSkel, Vt  # noqa: E402

OUT = os.path.join(os.path.dirname(__file__), "..", "usd_scenes", "skinned.usda")


def _tube(length: float, radius: float, rings: int, sides: int):
    pts, idx = [], []
    for i in range(rings + 1):
        x = length * i / rings
        for j in range(sides):
            a = 2 * math.pi * j / sides
            pts.append((x, radius * math.cos(a), radius * math.sin(a)))
    for i in range(rings):
        for j in range(sides):
            a, b = i * sides + j, i * sides + (j + 1) % sides
            idx += [a, b, b + sides, a + sides]
    return pts, [4] * (rings * sides), idx


def main(path: str = OUT) -> str:
    stage = new_stage(path, start=1, end=24, doc="warp_blur skinned: a two-joint UsdSkel arm swinging.")
    add_camera(stage, translate=(1.5, 1.0, 8.0), shutter=(-0.25, 0.25))
    add_dome(stage, color=(0.07, 0.08, 0.1))
    add_distant_light(stage, "/World/Sun", intensity=2.5, rotate=(-35, 30, 0))
    skin_mat = add_material(stage, "/World/Looks/Skin", diffuse=(0.75, 0.55, 0.4), roughness=0.6, specular=(0.04,) * 3)
    ground = add_material(stage, "/World/Looks/Ground", diffuse=(0.4, 0.4, 0.4), roughness=0.9)
    pts, c, i = grid(4, 4, 16.0, 16.0)
    add_mesh(stage, "/World/Ground", [(x, -1.5, -y) for x, y, _ in pts], c, i, material=ground)

    root = UsdSkel.Root.Define(stage, "/World/Arm")
    skel = UsdSkel.Skeleton.Define(stage, "/World/Arm/Skel")
    joints = ["shoulder", "shoulder/elbow"]
    skel.CreateJointsAttr(joints)
    bind_xf = [Gf.Matrix4d(1.0), Gf.Matrix4d(1.0).SetTranslate(Gf.Vec3d(1.5, 0, 0))]
    skel.CreateBindTransformsAttr(Vt.Matrix4dArray(bind_xf))
    skel.CreateRestTransformsAttr(Vt.Matrix4dArray([Gf.Matrix4d(1.0), Gf.Matrix4d(1.0).SetTranslate(Gf.Vec3d(1.5, 0, 0))]))
    anim = UsdSkel.Animation.Define(stage, "/World/Arm/Skel/Swing")
    anim.CreateJointsAttr(joints)
    anim.CreateTranslationsAttr(Vt.Vec3fArray([Gf.Vec3f(0, 0, 0), Gf.Vec3f(1.5, 0, 0)]))
    anim.CreateScalesAttr(Vt.Vec3hArray([Gf.Vec3h(1, 1, 1)] * 2))
    rot = anim.CreateRotationsAttr()
    for f in range(1, 25):
        a_sh = 35.0 * math.sin(0.5 * f)
        a_el = 60.0 * (0.5 + 0.5 * math.sin(0.7 * f))
        q_sh = Gf.Rotation(Gf.Vec3d(0, 0, 1), a_sh).GetQuat()
        q_el = Gf.Rotation(Gf.Vec3d(0, 0, 1), a_el).GetQuat()
        rot.Set(Vt.QuatfArray([Gf.Quatf(q_sh), Gf.Quatf(q_el)]), f)
    UsdSkel.BindingAPI.Apply(skel.GetPrim()).CreateAnimationSourceRel().SetTargets([anim.GetPath()])

    pts, counts, idx = _tube(3.0, 0.25, 12, 10)
    mesh = UsdGeom.Mesh.Define(stage, "/World/Arm/Mesh")
    mesh.CreatePointsAttr(Vt.Vec3fArray([Gf.Vec3f(*p) for p in pts]))
    mesh.CreateFaceVertexCountsAttr(counts)
    mesh.CreateFaceVertexIndicesAttr(idx)
    mesh.CreateSubdivisionSchemeAttr(UsdGeom.Tokens.catmullClark)
    binding = UsdSkel.BindingAPI.Apply(mesh.GetPrim())
    binding.CreateSkeletonRel().SetTargets([skel.GetPath()])
    ji, jw = [], []
    for x, _, _ in pts:
        w_el = min(max((x - 1.2) / 0.6, 0.0), 1.0)
        ji += [0, 1]
        jw += [1.0 - w_el, w_el]
    binding.CreateJointIndicesPrimvar(False, 2).Set(Vt.IntArray(ji))
    binding.CreateJointWeightsPrimvar(False, 2).Set(Vt.FloatArray(jw))
    binding.CreateGeomBindTransformAttr(Gf.Matrix4d(1.0))
    bind(mesh.GetPrim(), skin_mat)
    root.GetPrim()
    stage.GetRootLayer().Save()
    return path


if __name__ == "__main__":
    print(main(sys.argv[1] if len(sys.argv) > 1 else OUT))

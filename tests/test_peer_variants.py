"""bench/peer_variants.py: the emissive variant that Cycles and warp_blur both render keeps the
stage's geometry and motion (checked against UsdGeom itself), in forms Blender's importer reads."""

from __future__ import annotations

import os
import sys

import numpy as np
from pxr import Gf, Usd, UsdGeom

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
sys.path.insert(0, os.path.join(ROOT, "bench"))
from peer_variants import emissive_variant  # noqa: E402

SCENES = os.path.join(ROOT, "usd_scenes")


def test_a_cube_becomes_the_mesh_of_its_faces_with_the_same_bounds_and_motion(tmp_path):
    src = os.path.join(SCENES, "rotation.usda")
    dst = str(tmp_path / "rotation_emissive.usda")
    emissive_variant(src, dst, 2.0)
    before, after = Usd.Stage.Open(src), Usd.Stage.Open(dst)
    cube, mesh = before.GetPrimAtPath("/World/Box"), after.GetPrimAtPath("/World/Box")
    assert cube.IsA(UsdGeom.Cube) and mesh.IsA(UsdGeom.Mesh)
    assert len(UsdGeom.Mesh(mesh).GetFaceVertexCountsAttr().Get()) == 6
    cache = UsdGeom.BBoxCache(Usd.TimeCode.Default(), [UsdGeom.Tokens.default_])
    for t in (1.5, 2.0, 2.5):
        cache.SetTime(Usd.TimeCode(t))
        a, b = cache.ComputeWorldBound(cube).ComputeAlignedRange(), cache.ComputeWorldBound(mesh).ComputeAlignedRange()
        assert np.allclose(a.GetMin(), b.GetMin(), atol=1e-6) and np.allclose(a.GetMax(), b.GetMax(), atol=1e-6)
    # no light but the dome, no subdivision left
    assert not any(p.GetTypeName() in ("DistantLight", "SphereLight", "RectLight", "DiskLight") for p in after.Traverse())
    assert all(UsdGeom.Mesh(p).GetSubdivisionSchemeAttr().Get() == UsdGeom.Tokens.none
               for p in after.Traverse() if p.IsA(UsdGeom.Mesh))


def test_instancer_velocities_are_baked_into_shutter_samples_usd_agrees_with(tmp_path):
    src = os.path.join(SCENES, "large.usda")
    dst = str(tmp_path / "large_emissive.usda")
    emissive_variant(src, dst, 2.0)
    stages = Usd.Stage.Open(src), Usd.Stage.Open(dst)   # held: a prim needs its stage alive
    before, after = (UsdGeom.PointInstancer(st.GetPrimAtPath("/World/Rocks")) for st in stages)
    assert not after.GetVelocitiesAttr().HasAuthoredValue() or not after.GetVelocitiesAttr().Get(2.0)
    for t in (1.5, 2.0, 2.5):   # open, centre (linear between the two) and close
        want = before.ComputeInstanceTransformsAtTime(Usd.TimeCode(t), Usd.TimeCode(2.0))
        got = after.ComputeInstanceTransformsAtTime(Usd.TimeCode(t), Usd.TimeCode(t))
        w = np.array([np.array(m) for m in want])
        g = np.array([np.array(m) for m in got])
        assert w.shape == g.shape and np.abs(w - g).max() < 1e-3 * max(1.0, np.abs(w).max())
    assert isinstance(after.GetOrientationsAttr().Get(1.5)[0], Gf.Quath)

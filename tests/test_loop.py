"""Loop refinement (usd/loop.py): the stencil follows Loop's rules (checked by hand on an
icosahedron and a boundary fan), and a loop mesh renders as its refined surface in every method."""

import numpy as np
import pytest
import trimesh
from pxr import Gf, UsdGeom, Vt

import warp_blur as wb
from warp_blur.usd.loop import loop_refine


def test_one_level_follows_loops_rules():
    """Icosahedron (valence 5 everywhere): a vertex moves to (1 - 5 beta) P + beta sum(neighbours),
    an edge point is 3/8 of its ends + 1/8 of the opposite vertices; on an open fan the boundary
    vertices follow 3/4 P + 1/8 neighbours and the boundary edges' points are midpoints."""
    ico = trimesh.creation.icosahedron()
    pts, faces = np.asarray(ico.vertices), np.asarray(ico.faces)
    stencil, tris, parent, weights = loop_refine(np.full(len(faces), 3), faces.ravel(), len(pts), 1)
    out = stencil @ pts
    beta = (0.625 - (0.375 + 0.25 * np.cos(2 * np.pi / 5)) ** 2) / 5
    v = 0
    neighbours = sorted({int(x) for f in faces if v in f for x in f} - {v})
    np.testing.assert_allclose(out[v], (1 - 5 * beta) * pts[v] + beta * pts[neighbours].sum(axis=0), atol=1e-12)
    f0 = faces[0]
    a, b = f0[0], f0[1]
    others = [int(x) for f in faces if a in f and b in f for x in f if x not in (a, b)]
    mid = [i for i in range(len(pts), len(out))
           if np.allclose(out[i], 0.375 * (pts[a] + pts[b]) + 0.125 * pts[others].sum(axis=0))]
    assert len(mid) == 1
    assert len(tris) == 4 * len(faces) and (parent == np.repeat(np.arange(len(faces)), 4)).all()
    np.testing.assert_allclose(weights.sum(axis=2), 1.0)
    # an open fan of 4 triangles around a centre: the rim is boundary
    fan_pts = np.array([[0, 0, 0], [1, 0, 0], [0, 1, 0], [-1, 0, 0], [0, -1, 0]], np.float64)
    fan = np.array([[0, 1, 2], [0, 2, 3], [0, 3, 4], [0, 4, 1]])
    s_fan, _, _, _ = loop_refine(np.full(4, 3), fan.ravel(), 5, 1)
    got = s_fan @ fan_pts
    np.testing.assert_allclose(got[1], 0.75 * fan_pts[1] + 0.125 * (fan_pts[2] + fan_pts[4]))
    rim_mid = 0.5 * (fan_pts[1] + fan_pts[2])
    assert any(np.allclose(got[i], rim_mid) for i in range(5, len(got)))
    assert loop_refine(np.array([4]), np.arange(4), 4, 1) is None      # a quad: not a Loop mesh


def _ico_stage(path: str, scheme: str, moving: bool = False) -> str:
    from authoring import add_camera, new_stage
    ico = trimesh.creation.icosahedron()
    stage = new_stage(path)
    add_camera(stage)
    mesh = UsdGeom.Mesh.Define(stage, "/World/Ico")
    mesh.CreatePointsAttr(Vt.Vec3fArray([Gf.Vec3f(*map(float, p)) for p in ico.vertices]))
    mesh.CreateFaceVertexCountsAttr([3] * len(ico.faces))
    mesh.CreateFaceVertexIndicesAttr([int(i) for i in ico.faces.ravel()])
    mesh.CreateSubdivisionSchemeAttr(scheme)
    op = mesh.AddTranslateOp()
    if moving:
        op.Set(Gf.Vec3d(-0.5, 0, 0), 0.5)
        op.Set(Gf.Vec3d(0.5, 0, 0), 1.5)
    stage.GetRootLayer().Save()
    return path


def test_a_loop_mesh_renders_its_refined_surface(scene_path):
    """The refined icosahedron lies inside its cage (radius ~0.7 of 1): it covers clearly fewer
    pixels than the cage (rendered with scheme none), and the scene holds its refined triangles."""
    from warp_blur.usd.scene import Scene
    from warp_blur.usd.stage import Shutter, choose_camera, open_stage
    kw = dict(frame=1, method="accumulation", samples=1, resolution=(64, 48), shadows="off")
    cage = wb.render(_ico_stage(scene_path(), "none"), **kw).rgba[..., 3].sum()
    loop_path = _ico_stage(scene_path(), "loop")
    smooth = wb.render(loop_path, **kw).rgba[..., 3].sum()
    assert 0.35 * cage < smooth < 0.75 * cage
    stage = open_stage(loop_path)
    assert Scene(stage, choose_camera(stage, None), 1.0, Shutter(1.0, 1.0)).num_triangles == 20 * 16


@pytest.mark.parametrize("method", ["analytic", "stochastic", "velocity"])
def test_a_moving_loop_mesh_renders_in_every_method(scene_path, method):
    path = _ico_stage(scene_path(), "loop", moving=True)
    ref = wb.render(path, frame=1, method="accumulation", samples=32, resolution=(64, 48), shadows="off").rgba
    got = wb.render(path, frame=1, method=method, samples=16, resolution=(64, 48), shadows="off").rgba
    assert np.isfinite(got).all() and got[..., 3].max() > 0.9
    if method != "velocity":
        assert np.sqrt(((got - ref) ** 2).mean()) < 0.03

"""USD -> NumPy: positions agree with UsdGeom's own transforms; instancers, gprims, purpose,
visibility, upAxis Z and large coordinates are read as authored."""

import numpy as np
import pytest
from pxr import Gf, Sdf, UsdGeom, Vt

from warp_blur.core.errors import InvalidGeometryError
from warp_blur.usd.normals import smooth_normals_for, vertex_normals
from warp_blur.usd.scene import Scene
from warp_blur.usd.stage import Shutter, choose_camera, open_stage


def _scene(path, frame=1.0, shutter=(0.5, 1.5), **kw):
    stage = open_stage(path)
    cam = choose_camera(stage, None)
    return stage, cam, Scene(stage, cam, frame, Shutter(*shutter), **kw)


def test_positions_agree_with_usdgeom(scene_path):
    from authoring import add_camera, add_mesh, new_stage
    path = scene_path()
    stage = new_stage(path)
    add_camera(stage, translate_samples={0: (0, 1, 10), 2: (1, 0, 8)}, rotate_axis="Y", rotate_samples={0: -10, 2: 20})
    parent = UsdGeom.Xform.Define(stage, "/World/Parent")
    parent.AddRotateZOp().Set(30.0, 0.0)
    parent.GetPrim().GetAttribute("xformOp:rotateZ").Set(90.0, 2.0)
    add_mesh(stage, "/World/Parent/Tri", [(0, 0, 0), (1, 0, 0), (0, 1, 0)], [3], [0, 1, 2],
             translate_samples={0: (0, 0, 0), 2: (2, 1, -1)}, rotate_axis="X", rotate_samples={0: 0, 2: 45})
    stage.GetRootLayer().Save()
    stage, cam, scene = _scene(path)
    for t in (0.5, 0.8, 0.8, 1.3, 0.5):   # repeated times: the camera's inverse is kept while it holds
        snap = scene.snapshot(t)
        prim = stage.GetPrimAtPath("/World/Parent/Tri")
        l2w = UsdGeom.Xformable(prim).ComputeLocalToWorldTransform(t)
        c2w = UsdGeom.Xformable(cam.GetPrim()).ComputeLocalToWorldTransform(t)
        w2c = c2w.GetInverse()
        pts = UsdGeom.Mesh(prim).GetPointsAttr().Get(t)
        expect = np.array([list(w2c.Transform(l2w.Transform(Gf.Vec3d(p)))) for p in pts])
        np.testing.assert_allclose(snap.positions, expect, atol=1e-9)
        np.testing.assert_allclose(snap.cam_from_world, np.array(w2c), atol=1e-12)


def test_point_instancer_instances(scene_path):
    from authoring import add_camera, new_stage
    path = scene_path()
    stage = new_stage(path)
    add_camera(stage)
    inst = UsdGeom.PointInstancer.Define(stage, "/World/Inst")
    cube = UsdGeom.Cube.Define(stage, "/World/Inst/Protos/Cube")
    cube.CreateSizeAttr(0.5)
    inst.CreatePrototypesRel().SetTargets([cube.GetPath()])
    inst.CreateProtoIndicesAttr(Vt.IntArray([0, 0, 0]))
    # velocities apply to time-sampled positions (USD ignores them for a default value)
    inst.CreatePositionsAttr().Set(Vt.Vec3fArray([Gf.Vec3f(-2, 0, 0), Gf.Vec3f(0, 0, 0), Gf.Vec3f(2, 0, 0)]), 1.0)
    inst.CreateVelocitiesAttr().Set(Vt.Vec3fArray([Gf.Vec3f(24, 0, 0)] * 3), 1.0)  # 1 unit/frame at 24 tcps
    stage.GetRootLayer().Save()
    stage, cam, scene = _scene(path)
    assert scene.num_triangles == 3 * 12
    a, b = scene.snapshot(1.0), scene.snapshot(1.5)
    # velocities: positions move 0.5 units in x over half a frame (USD's own ComputeInstanceTransformsAtTime)
    np.testing.assert_allclose(b.positions - a.positions, np.tile([0.5, 0, 0], (len(a.positions), 1)), atol=1e-6)
    xs = a.positions[:, 0].reshape(3, -1).mean(axis=1)
    np.testing.assert_allclose(xs, [-2, 0, 2], atol=1e-6)


def test_gprims_purpose_and_visibility(scene_path):
    from authoring import add_camera, new_stage
    path = scene_path()
    stage = new_stage(path)
    add_camera(stage)
    UsdGeom.Sphere.Define(stage, "/World/S")
    UsdGeom.Cylinder.Define(stage, "/World/C")
    UsdGeom.Cone.Define(stage, "/World/K")
    UsdGeom.Capsule.Define(stage, "/World/P")
    UsdGeom.Plane.Define(stage, "/World/L")
    proxy = UsdGeom.Cube.Define(stage, "/World/Proxy")
    proxy.CreatePurposeAttr(UsdGeom.Tokens.proxy)
    hidden = UsdGeom.Cube.Define(stage, "/World/Blink")
    hidden.CreateVisibilityAttr().Set(UsdGeom.Tokens.invisible, 1.25)
    hidden.GetVisibilityAttr().Set(UsdGeom.Tokens.inherited, 0.0)
    group = UsdGeom.Xform.Define(stage, "/World/Group")   # animated on a parent: the child blinks too
    group.CreateVisibilityAttr().Set(UsdGeom.Tokens.inherited, 0.0)
    group.GetVisibilityAttr().Set(UsdGeom.Tokens.invisible, 1.25)
    UsdGeom.Cube.Define(stage, "/World/Group/Child")
    UsdGeom.BasisCurves.Define(stage, "/World/Curves")
    stage.GetRootLayer().Save()
    stage, cam, scene = _scene(path)
    paths = [u.path for u in scene.units]
    assert paths == ["/World/S", "/World/C", "/World/K", "/World/P", "/World/L", "/World/Blink",
                     "/World/Group/Child"]
    for name in ("/World/Blink", "/World/Group/Child"):
        blink = scene.tri_unit == paths.index(name)
        assert scene.snapshot(1.0).tri_visible[blink].all() and scene.snapshot(0.9).tri_visible[blink].all()
        assert not scene.snapshot(1.3).tri_visible[blink].any()
    still = scene.tri_unit == paths.index("/World/S")   # never animated: its visibility is read once
    assert scene.snapshot(1.3).tri_visible[still].all() and scene.units[0].visibility == (False, True)
    # the sphere's tessellation lies on the radius-1 sphere
    s = scene.snapshot(1.0).positions[: scene.units[0].num_points] - np.array([0, 0, -10.0])
    np.testing.assert_allclose(np.linalg.norm(s, axis=1), 1.0, atol=1e-6)


def test_implicit_gprims_of_the_same_dimensions_share_one_read_only_tessellation(scene_path):
    """Proxy shapes: spheres of one radius share one tessellation (made once), each prim placed by
    its own transform; another radius, axis or kind makes its own."""
    from authoring import add_camera, new_stage

    from warp_blur.usd.tessellate import _trimesh_shape
    path = scene_path()
    stage = new_stage(path)
    add_camera(stage)
    for i in range(3):
        UsdGeom.Sphere.Define(stage, f"/World/S{i}").AddTranslateOp().Set(Gf.Vec3d(3.0 * i, 0, 0))
    UsdGeom.Sphere.Define(stage, "/World/Big").CreateRadiusAttr(2.0)
    UsdGeom.Cylinder.Define(stage, "/World/CZ")
    long_x = UsdGeom.Cylinder.Define(stage, "/World/CX")
    long_x.CreateAxisAttr("X")
    long_x.CreateHeightAttr(4.0)
    stage.GetRootLayer().Save()
    _trimesh_shape.cache_clear()
    _, _, scene = _scene(path)
    pts = {u.path: u.points_at(1.0) for u in scene.units}
    assert pts["/World/S0"] is pts["/World/S1"] is pts["/World/S2"] and not pts["/World/S0"].flags.writeable
    assert _trimesh_shape.cache_info().misses == 4    # radius 1, radius 2, a z and an x cylinder
    np.testing.assert_allclose(np.linalg.norm(pts["/World/Big"], axis=1), 2.0, atol=1e-6)
    np.testing.assert_allclose(np.abs(pts["/World/CX"]).max(axis=0), [2.0, 1.0, 1.0], atol=1e-6)   # height along x
    centres = [scene.snapshot(1.0).positions[scene.tri_vertices[scene.tri_unit == i]].mean(axis=(0, 1))
               for i in range(3)]
    np.testing.assert_allclose(np.array(centres)[:, 0] - centres[0][0], [0.0, 3.0, 6.0], atol=1e-6)


def test_invalid_geometry_is_named_or_skipped(scene_path):
    from authoring import add_camera, add_mesh, new_stage
    path = scene_path()
    stage = new_stage(path)
    add_camera(stage)
    add_mesh(stage, "/World/Bad", [(0, 0, 0), (1, 0, 0), (0, 1, 0)], [3], [0, 1, 7])
    add_mesh(stage, "/World/NaN", [(0, 0, 0), (float("nan"), 0, 0), (0, 1, 0)], [3], [0, 1, 2])
    add_mesh(stage, "/World/Good", [(0, 0, 0), (1, 0, 0), (0, 1, 0)], [3], [0, 1, 2])
    stage.GetRootLayer().Save()
    with pytest.raises(InvalidGeometryError, match="/World/Bad"):
        _scene(path)
    _, _, scene = _scene(path, skip_invalid=True)
    assert [u.path for u in scene.units] == ["/World/Good"]


def test_a_negative_face_vertex_count_is_named_not_wrapped_around(scene_path):
    """Counts [-3, 6] add up to six indices, but no face has -3 corners: named, not read with
    the second face starting three indices before the first."""
    from authoring import add_camera, add_mesh, new_stage
    path = scene_path()
    stage = new_stage(path)
    add_camera(stage)
    add_mesh(stage, "/World/Negative", [(0, 0, 0), (1, 0, 0), (0, 1, 0), (1, 1, 0)], [-3, 6], [0, 1, 2, 1, 3, 2])
    add_mesh(stage, "/World/Good", [(0, 0, 0), (1, 0, 0), (0, 1, 0)], [3], [0, 1, 2])
    stage.GetRootLayer().Save()
    with pytest.raises(InvalidGeometryError, match="/World/Negative: negative faceVertexCount -3"):
        _scene(path)
    _, _, scene = _scene(path, skip_invalid=True)
    assert [u.path for u in scene.units] == ["/World/Good"]


def test_unresolved_references_and_payloads_are_warned_about_once_and_the_rest_renders(tmp_path, scene_path):
    from authoring import add_camera, add_mesh, new_stage

    from warp_blur.core import log
    path = scene_path()
    stage = new_stage(path)
    add_camera(stage)
    add_mesh(stage, "/World/Good", [(0, 0, 0), (1, 0, 0), (0, 1, 0)], [3], [0, 1, 2])
    stage.DefinePrim("/World/Ref", "Xform").GetReferences().AddReference(str(tmp_path / "gone.usda"))
    stage.DefinePrim("/World/Pay", "Xform").GetPayloads().AddPayload(str(tmp_path / "gone_too.usda"))
    stage.GetRootLayer().Save()
    log.reset()
    _, _, scene = _scene(path)
    assert [u.path for u in scene.units] == ["/World/Good"]
    said = [w for w in log.take_warnings() if "composition" in w]
    assert len(said) == 1 and "2 composition errors" in said[0], said
    assert "gone.usda" in said[0] and "gone_too.usda" in said[0] and "\n" not in said[0]
    _scene(path)
    assert not [w for w in log.take_warnings() if "composition" in w]   # once per stage


def test_a_stage_that_composes_cleanly_is_not_warned_about():
    import os

    from warp_blur.core import log
    log.reset()
    _scene(os.path.join(os.path.dirname(os.path.dirname(__file__)), "usd_scenes", "demo.usda"))
    assert not [w for w in log.take_warnings() if "composition" in w]


def test_up_axis_z_and_units_render_as_authored(scene_path):
    from authoring import add_camera, add_mesh, new_stage
    path = scene_path()
    stage = new_stage(path, up="Z", meters_per_unit=0.01)
    add_camera(stage, translate=(0, 0, 1000), clipping=(1, 10000))
    add_mesh(stage, "/World/T", [(0, 0, 0), (100, 0, 0), (0, 100, 0)], [3], [0, 1, 2])
    stage.GetRootLayer().Save()
    _, _, scene = _scene(path)
    np.testing.assert_allclose(scene.snapshot(1.0).positions, [[0, 0, -1000], [100, 0, -1000], [0, 100, -1000]], atol=1e-9)


def test_large_world_coordinates_stay_precise(scene_path):
    from authoring import add_camera, add_mesh, new_stage
    path = scene_path()
    stage = new_stage(path)
    off = 1.0e6
    add_camera(stage, translate=(off, off, off + 10))
    add_mesh(stage, "/World/T", [(0, 0, 0), (1e-3, 0, 0), (0, 1e-3, 0)], [3], [0, 1, 2], translate=(off, off, off))
    stage.GetRootLayer().Save()
    _, _, scene = _scene(path)
    p = scene.snapshot(1.0).positions.astype(np.float32)  # what kernels see
    np.testing.assert_allclose(p, [[0, 0, -10], [1e-3, 0, -10], [0, 1e-3, -10]], atol=1e-6)


def test_messy_usd_references_payloads_instances_matrices(tmp_path, scene_path):
    """References, payloads, instanceable prims, xformOp:transform matrices, a subdivision mesh
    (rendered as its cage) and an unsupported prim (warned about once) compose as USD says."""
    from authoring import add_camera, new_stage
    from pxr import Gf, Usd, UsdGeom

    from warp_blur.core import log
    asset = str(tmp_path / "asset.usda")
    a = Usd.Stage.CreateNew(asset)
    root = UsdGeom.Xform.Define(a, "/Asset")
    a.SetDefaultPrim(root.GetPrim())
    m = UsdGeom.Mesh.Define(a, "/Asset/Cage")
    m.CreatePointsAttr([(0, 0, 0), (1, 0, 0), (1, 1, 0), (0, 1, 0)])
    m.CreateFaceVertexCountsAttr([4])
    m.CreateFaceVertexIndicesAttr([0, 1, 2, 3])
    m.CreateSubdivisionSchemeAttr(UsdGeom.Tokens.catmullClark)
    UsdGeom.NurbsPatch.Define(a, "/Asset/Dust").CreatePointsAttr([(0, 0, 0)])   # not rendered
    a.GetRootLayer().Save()

    path = scene_path()
    stage = new_stage(path)
    add_camera(stage)
    for i, kind in enumerate(["ref", "ref", "payload"]):
        prim = stage.DefinePrim(f"/World/Copy{i}", "Xform")
        if kind == "ref":
            prim.GetReferences().AddReference(asset)
            prim.SetInstanceable(True)
        else:
            prim.GetPayloads().AddPayload(asset)
        op = UsdGeom.Xformable(prim).AddTransformOp()
        op.Set(Gf.Matrix4d(1.0).SetTranslate(Gf.Vec3d(2.0 * i, 0, 0)))
    stage.GetRootLayer().Save()
    log.reset()
    _, _, scene = _scene(path)
    assert scene.num_triangles == 3 * 32          # a catmullClark quad refined twice: 16 quads
    assert all(u.flags & 2 for u in scene.units)  # subdivision surface: smooth normals
    xs = scene.snapshot(1.0).positions[:, 0].reshape(3, -1).min(axis=1)   # its corners stay put
    np.testing.assert_allclose(xs, [0.0, 2.0, 4.0], atol=1e-9)
    warnings = log.take_warnings()
    dust = [w for w in warnings if "Dust" in w and "not rendered" in w]
    assert len(dust) == 3  # once per prim (three composed copies), each naming its path
    _scene(path)
    assert not [w for w in log.take_warnings() if "Dust" in w]  # never repeated


def _numpy_vertex_normals(positions: np.ndarray, tris: np.ndarray) -> np.ndarray:
    """The oracle: area-weighted vertex normals by np.cross, np.bincount and np.linalg.norm."""
    a, b, c = positions[tris[:, 0]], positions[tris[:, 1]], positions[tris[:, 2]]
    fn = np.cross(b - a, c - a)
    idx = tris.ravel()
    n = np.stack([np.bincount(idx, weights=np.repeat(fn[:, k], 3), minlength=len(positions)) for k in range(3)],
                 axis=1)
    return (n / np.maximum(np.linalg.norm(n, axis=1, keepdims=True), 1e-30)).astype(np.float32)


def test_smooth_normals_equal_numpys_bit_for_bit():
    """Random meshes (degenerate triangles, repeated and unused vertices, scales from 1e-3 to 1e6):
    the kernels' normals equal NumPy's exactly, so moving them to Warp changed no image."""
    rng = np.random.default_rng(7)
    for trial in range(30):
        v = int(rng.integers(1, 500))
        tris = rng.integers(0, v, (int(rng.integers(0, 1500)), 3)).astype(np.int32)
        positions = rng.normal(size=(v, 3)) * 10 ** rng.uniform(-3, 6) + rng.normal(size=3) * 10 ** rng.uniform(0, 6)
        np.testing.assert_array_equal(vertex_normals(positions, tris), _numpy_vertex_normals(positions, tris))


def test_smooth_normals_of_a_large_mesh_over_bands_equal_numpys():
    """Past CHEAP_PASS_SERIAL_ITEMS triangles and vertices the two kernels run over bands on every
    core; each band writes its own triangles and vertices, so the normals stay NumPy's exactly."""
    from warp_blur.core.parallel import CHEAP_PASS_SERIAL_ITEMS
    rng = np.random.default_rng(9)
    v = 2 * CHEAP_PASS_SERIAL_ITEMS + 17
    tris = rng.integers(0, v, (3 * CHEAP_PASS_SERIAL_ITEMS + 5, 3)).astype(np.int32)
    positions = rng.normal(size=(v, 3)) * 50.0 + 1.0e4
    np.testing.assert_array_equal(vertex_normals(positions, tris), _numpy_vertex_normals(positions, tris))


def test_smooth_normals_are_kept_per_topology():
    """A topology seen again gets its kept corner lists; another one (same size) does not."""
    rng = np.random.default_rng(8)
    tris = rng.integers(0, 50, (80, 3)).astype(np.int32)
    first = smooth_normals_for(tris, 50)
    assert smooth_normals_for(tris.copy(), 50) is first
    other = tris.copy()
    other[3, 1] = (other[3, 1] + 1) % 50
    assert smooth_normals_for(other, 50) is not first
    positions = rng.normal(size=(50, 3))
    np.testing.assert_array_equal(smooth_normals_for(other, 50)(positions), _numpy_vertex_normals(positions, other))


@pytest.mark.parametrize("indices,positions", [([0, -1, 0], 3), ([0, 7, 0], 3), ([0, 0, 0], 2)])
def test_an_invalid_point_instancer_is_named_or_skipped(scene_path, indices, positions):
    """protoIndices outside the prototypes, or positions USD cannot match to them: an error naming
    the instancer (found by the fuzzer as a raw IndexError), or dropped with --skip-invalid."""
    from authoring import add_camera, add_quad, new_stage
    from warp_blur.core import log
    path = scene_path()
    stage = new_stage(path)
    add_camera(stage)
    add_quad(stage, "/World/Quad", 1.0, 1.0, translate=(0, 0, -2))
    inst = UsdGeom.PointInstancer.Define(stage, "/World/Inst")
    cube = UsdGeom.Cube.Define(stage, "/World/Inst/Protos/Cube")
    inst.CreatePrototypesRel().SetTargets([cube.GetPath()])
    inst.CreateProtoIndicesAttr(Vt.IntArray(indices))
    inst.CreatePositionsAttr(Vt.Vec3fArray([Gf.Vec3f(i, 0, 0) for i in range(positions)]))
    stage.GetRootLayer().Save()
    with pytest.raises(InvalidGeometryError, match="/World/Inst"):
        _scene(path)
    log.reset()
    _, _, scene = _scene(path, skip_invalid=True)
    assert [u.path for u in scene.units] == ["/World/Quad"]
    assert any("/World/Inst" in w for w in log.take_warnings())


def test_geomsubset_material_bindings_colour_their_faces(scene_path):
    """A mesh bound to green with a materialBind GeomSubset of its right face bound to red
    (issue 19): each face renders in its own material, in every method."""
    from authoring import add_camera, add_material, add_mesh, bind, new_stage
    from pxr import UsdShade

    import warp_blur as wb
    path = scene_path()
    stage = new_stage(path)
    add_camera(stage)
    green = add_material(stage, "/World/Looks/Green", emissive=(0.0, 1.0, 0.0))
    red = add_material(stage, "/World/Looks/Red", emissive=(1.0, 0.0, 0.0))
    mesh = add_mesh(stage, "/World/Two", [(-2, -1, 0), (0, -1, 0), (0, 1, 0), (-2, 1, 0), (2, -1, 0), (2, 1, 0)],
                    [4, 4], [0, 1, 2, 3, 1, 4, 5, 2], material=green,
                    translate_samples={0: (-0.05, 0, 0), 2: (0.05, 0, 0)})   # moving: every method's own path
    binding = UsdShade.MaterialBindingAPI.Apply(mesh.GetPrim())
    subset = binding.CreateMaterialBindSubset("right", Vt.IntArray([1]), UsdGeom.Tokens.face)
    bind(subset.GetPrim(), red)
    stage.GetRootLayer().Save()
    for method in ("analytic", "accumulation", "stochastic", "velocity"):
        rgba = wb.render(path, frame=1, method=method, resolution=(64, 48), samples=2, shadows="off").rgba
        left, right = rgba[24, 20, :3], rgba[24, 44, :3]
        assert np.allclose(left, (0, 1, 0), atol=1e-4) and np.allclose(right, (1, 0, 0), atol=1e-4), method


def _normals_stage(path: str, interpolation: str, hard: bool = False) -> str:
    """A flat quad (subdivisionScheme none) in the XY plane whose authored normals lean 45° to +X,
    spun 90° about Z by its transform: shading must use the authored normals, moved by the prim."""
    from authoring import add_camera, add_mesh, new_stage
    from pxr import Gf, UsdGeom, Vt
    stage = new_stage(path)
    add_camera(stage)
    mesh = add_mesh(stage, "/World/Quad", [(-1, -1, 0), (1, -1, 0), (1, 1, 0), (-1, 1, 0)], [4], [0, 1, 2, 3],
                    rotate_axis="Z", rotate=90.0)
    n = Gf.Vec3f(0.7071068, 0.0, 0.7071068)
    count = 4
    values = [n] * count
    if hard:
        values[0] = Gf.Vec3f(0.0, 0.0, 1.0)
    pv = UsdGeom.PrimvarsAPI(mesh).CreatePrimvar("normals", Sdf.ValueTypeNames.Normal3fArray, interpolation)
    pv.Set(Vt.Vec3fArray(values))
    stage.GetRootLayer().Save()
    return path


@pytest.mark.parametrize("interpolation", ["vertex", "faceVarying"])
def test_authored_normals_shade_and_move_with_the_prim(scene_path, interpolation):
    path = _normals_stage(scene_path(), interpolation)
    _, _, scene = _scene(path)
    assert scene.any_smooth
    snap = scene.snapshot(1.0)
    # the 45° lean to +X, turned 90° about Z, leans to +Y (the camera looks down -Z unrotated)
    np.testing.assert_allclose(snap.normals, np.tile([[0.0, 0.7071068, 0.7071068]], (4, 1)), atol=1e-5)


def test_hard_edged_face_varying_normals_shade_each_side_with_its_own(scene_path):
    """Two quads sharing an edge whose corners there carry different normals (a hard edge): the
    edge's two points are copied, one per side, so every triangle corner shades with its face's
    authored normal, and the copies sit exactly where the points are."""
    from authoring import add_camera, add_mesh, new_stage
    path = scene_path()
    stage = new_stage(path)
    add_camera(stage)
    mesh = add_mesh(stage, "/World/Fold", [(-2, -1, 0), (0, -1, 0), (2, -1, 0), (-2, 1, 0), (0, 1, 0), (2, 1, 0)],
                    [4, 4], [0, 1, 4, 3, 1, 2, 5, 4])
    left, right = Gf.Vec3f(-0.6, 0.0, 0.8), Gf.Vec3f(0.6, 0.0, 0.8)
    pv = UsdGeom.PrimvarsAPI(mesh).CreatePrimvar("normals", Sdf.ValueTypeNames.Normal3fArray, "faceVarying")
    pv.Set(Vt.Vec3fArray([left] * 4 + [right] * 4))
    stage.GetRootLayer().Save()
    _, _, scene = _scene(path)
    assert scene.any_smooth
    snap = scene.snapshot(1.0)
    assert len(snap.positions) == 8                        # 6 points, the 2 on the hard edge twice
    tris = scene.tri_vertices
    corner_normals = snap.normals[tris]                    # (T, 3, 3)
    x_centre = snap.positions[tris].mean(axis=1)[:, 0]     # left quad's triangles have x < 0
    for t in range(len(tris)):
        want = np.array([-0.6, 0.0, 0.8]) if x_centre[t] < 0 else np.array([0.6, 0.0, 0.8])
        np.testing.assert_allclose(corner_normals[t], np.tile(want, (3, 1)), atol=1e-5)
    assert len(np.unique(np.round(snap.positions, 9), axis=0)) == 6


def _assert_placed_like_usdgeom(scene, cam, snap, t):
    """Every mesh unit of `scene` (frame 1) in snapshot `snap` at shutter time t: its points where
    UsdGeom puts them at its own motion blur scale's time, seen from the camera at t, and its
    visibility as UsdGeom computes it."""
    w2c = UsdGeom.Xformable(cam.GetPrim()).ComputeLocalToWorldTransform(t).GetInverse()
    for ui, u in enumerate(scene.units):
        t_prim = 1.0 + (t - 1.0) * u.blur_scale
        l2w = UsdGeom.Xformable(u.prim).ComputeLocalToWorldTransform(t_prim)
        pts = UsdGeom.Mesh(u.prim).GetPointsAttr().Get(t_prim)
        expect = np.array([list(w2c.Transform(l2w.Transform(Gf.Vec3d(p)))) for p in pts])
        o = scene.unit_vertex_offsets[ui]
        np.testing.assert_allclose(snap.positions[o:o + u.num_points], expect, atol=1e-9)
        visible = UsdGeom.Imageable(u.prim).ComputeVisibility(t_prim) != UsdGeom.Tokens.invisible
        assert snap.tri_visible[scene.tri_unit == ui].all() == visible


def test_small_prims_placed_together_agree_with_usdgeom_and_with_one_by_one(scene_path, monkeypatch):
    """Scene.snapshot places many small prims in one batch (usd/units.py): each prim's points as
    UsdGeom transforms them (at its own motion blur scale's time), its visibility as authored, and
    the same positions (to float64 rounding) as placing them one by one."""
    from authoring import add_camera, add_quad, new_stage

    import warp_blur.usd.units as units
    path = scene_path()
    stage = new_stage(path)
    add_camera(stage, translate_samples={0: (0, 1, 10), 2: (1, 0, 8)})
    for i in range(12):
        q = add_quad(stage, f"/World/Q{i}", 0.3, 0.2, translate_samples={0: (i * 0.3 - 2, 0, -i), 2: (i * 0.2, 1, 0)},
                     rotate_axis="Z", rotate_samples={0: 0, 2: 30 * i})
        if i % 3 == 0:
            UsdGeom.MotionAPI.Apply(q.GetPrim()).CreateMotionBlurScaleAttr(0.5)
    UsdGeom.Imageable(stage.GetPrimAtPath("/World/Q4")).GetVisibilityAttr().Set("invisible", 1.2)
    UsdGeom.Imageable(stage.GetPrimAtPath("/World/Q4")).GetVisibilityAttr().Set("inherited", 0.5)
    moving = UsdGeom.Mesh(stage.GetPrimAtPath("/World/Q5")).GetPointsAttr()
    moving.Set([(-0.3, -0.2, 0), (0.3, -0.2, 0), (0.3, 0.2, 0), (-0.3, 0.2, 0)], 0.5)
    moving.Set([(-0.5, -0.2, 0), (0.3, -0.4, 0), (0.3, 0.6, 0), (-0.3, 0.2, 0)], 1.5)
    stage.GetRootLayer().Save()
    stage, cam, scene = _scene(path)
    groups = scene._small_unit_groups()
    assert sorted(len(g.units) for g in groups) == [4, 8]   # blur scales 0.5 and 1
    for t in (0.5, 0.9, 1.3, 0.7, 1.1, 1.5, 0.6):   # the first four prim by prim, then batched
        snap = scene.snapshot(t)
        _assert_placed_like_usdgeom(scene, cam, snap, t)
        monkeypatch.setattr(units, "SMALL_UNIT_POINTS", 0)
        alone = Scene(stage, cam, 1.0, Shutter(0.5, 1.5)).snapshot(t)
        monkeypatch.undo()
        np.testing.assert_allclose(snap.positions, alone.positions, rtol=1e-15, atol=1e-15)
        assert np.array_equal(snap.tri_visible, alone.tri_visible)
    assert not scene.snapshot(1.3).tri_visible[scene.tri_unit == 4].any()    # Q4 hides at 1.2
    # after units.USD_PLACEMENTS_FIRST snapshots the batched transforms (xform_ops.py) placed every quad
    assert all(g.linear is not None and len(g.linear[0]) == len(g.units) for g in groups)


def test_still_prims_are_read_once_a_frame_and_placed_like_usdgeom(scene_path):
    """A set's prims that hold still (no animated op on them or an ancestor, still points) are
    grouped apart: their transforms and points are read at the first snapshot only, and their
    camera-space block is kept while the camera holds still. Every snapshot must still place every
    prim where UsdGeom puts it, with its authored visibility, whether the camera moves or not;
    prims under an animated parent are not taken as still."""
    from authoring import add_camera, add_quad, new_stage

    from warp_blur.usd.stage import transform_may_vary
    for camera_moves in (True, False):
        path = scene_path()
        stage = new_stage(path)
        if camera_moves:
            add_camera(stage, translate_samples={0: (0, 1, 10), 2: (1, 0, 8)})
        else:
            add_camera(stage, translate=(0, 1, 10))
        for i in range(6):
            add_quad(stage, f"/World/Set/S{i}", 0.3, 0.2, translate=(i * 0.4 - 1, 0.5, -i))
        arm = UsdGeom.Xform.Define(stage, "/World/Arm")
        arm.AddRotateZOp().Set(0.0, 0.0)
        arm.GetPrim().GetAttribute("xformOp:rotateZ").Set(40.0, 2.0)
        for i in range(3):
            add_quad(stage, f"/World/Arm/A{i}", 0.3, 0.2, translate=(i * 0.5, -0.5, 0))
        UsdGeom.Imageable(stage.GetPrimAtPath("/World/Set/S2")).GetVisibilityAttr().Set("inherited", 0.5)
        UsdGeom.Imageable(stage.GetPrimAtPath("/World/Set/S2")).GetVisibilityAttr().Set("invisible", 1.2)
        stage.GetRootLayer().Save()
        stage, cam, scene = _scene(path)
        memo = {}
        varies = {u.path: transform_may_vary(u.prim, memo) for u in scene.units}
        assert varies == {**{f"/World/Set/S{i}": False for i in range(6)}, **{f"/World/Arm/A{i}": True for i in range(3)}}
        groups = {g.still: g for g in scene._small_unit_groups()}
        assert sorted(scene.units[ui].path for ui in groups[True].units) == [f"/World/Set/S{i}" for i in range(6)]
        assert sorted(scene.units[ui].path for ui in groups[False].units) == [f"/World/Arm/A{i}" for i in range(3)]
        blocks = []
        for t in (0.5, 0.9, 1.3, 0.7):
            snap = scene.snapshot(t)
            blocks.append(groups[True].last_placed[1])
            _assert_placed_like_usdgeom(scene, cam, snap, t)
        # a still camera keeps the still group's block (one array); a moving one places it anew
        assert all(b is blocks[0] for b in blocks) != camera_moves


def _sphere_field(path, distances, radius=0.5):
    """An instancer of spheres at these distances in front of a camera at the origin looking -Z,
    and one Sphere prim per distance beside them."""
    from authoring import add_camera, new_stage
    stage = new_stage(path)
    add_camera(stage, translate=(0, 0, 0))
    inst = UsdGeom.PointInstancer.Define(stage, "/World/Inst")
    ball = UsdGeom.Sphere.Define(stage, "/World/Inst/Protos/Ball")
    ball.CreateRadiusAttr(radius)
    inst.CreatePrototypesRel().SetTargets([ball.GetPath()])
    inst.CreateProtoIndicesAttr(Vt.IntArray([0] * len(distances)))
    inst.CreatePositionsAttr().Set(Vt.Vec3fArray([Gf.Vec3f(0.1 * d, 0, -d) for d in distances]))
    for i, d in enumerate(distances):
        s = UsdGeom.Sphere.Define(stage, f"/World/S{i}")
        s.CreateRadiusAttr(radius)
        s.AddTranslateOp().Set(Gf.Vec3d(-0.1 * d, 0, -d))
    stage.GetRootLayer().Save()
    return path


def test_spheres_small_on_screen_take_fewer_triangles(scene_path):
    """An instancer's sphere instances are split by the icosphere level their size on screen asks
    for (one unit a level, every instance kept once); Sphere prims take theirs alone; with no
    image projection known, every sphere keeps the full level."""
    from warp_blur.usd.stage import projection_at
    from warp_blur.usd.tessellate import SPHERE_LEVEL_MAX, sphere_levels
    distances = [2.0, 40.0, 300.0, 3000.0]
    path = _sphere_field(scene_path(), distances)
    stage = open_stage(path)
    cam = choose_camera(stage, None)
    proj = projection_at(cam, 1.0, (320, 240))
    scene = Scene(stage, cam, 1.0, Shutter(0.5, 1.5), proj=proj)
    # on-axis radius in pixels: r f / (d - r), f = 320 px across a 24 mm aperture at 24 mm focal length
    expect = sphere_levels(np.array([0.5 * 320 / (d - 0.5) for d in distances]))
    assert list(expect) == [3, 3, 2, 0]
    tris = {1: 80, 0: 20, 2: 320, 3: 1280}
    by_name = {u.path: u for u in scene.units}
    inst_units = [u for name, u in by_name.items() if name.startswith("/World/Inst")]
    assert sorted(u.num_instances for u in inst_units) == [1, 1, 2]
    assert {name for name in by_name if name.startswith("/World/Inst")} == {
        "/World/Inst (prototype Ball)", "/World/Inst (prototype Ball) level 2", "/World/Inst (prototype Ball) level 0"}
    assert sum(len(u.local_tris) * u.num_instances for u in inst_units) == sum(tris[int(k)] for k in expect)
    assert [len(by_name[f"/World/S{i}"].local_tris) for i in range(4)] == [tris[int(k)] for k in expect]
    # the instances' positions are where USD puts them, whatever unit holds them
    snap = scene.snapshot(1.0)
    assert np.isfinite(snap.positions).all() and scene.num_triangles == 2 * sum(tris[int(k)] for k in expect)
    plain = Scene(stage, cam, 1.0, Shutter(0.5, 1.5))   # no projection: the full level for all
    assert plain.num_triangles == 8 * 1280 and SPHERE_LEVEL_MAX == 3


def test_a_sphere_moving_away_changes_level_between_frames(scene_path):
    """A renderer keeps a still prim's unit across frames; a sphere whose size on screen asks for
    another level at the next frame is read again at that level, not reused."""
    import warp_blur as wb
    from authoring import add_camera, new_stage
    path = scene_path()
    stage = new_stage(path)
    add_camera(stage, translate=(0, 0, 0))
    s = UsdGeom.Sphere.Define(stage, "/World/Ball")
    s.CreateRadiusAttr(0.5)
    op = s.AddTranslateOp()
    op.Set(Gf.Vec3d(0, 0, -3), 0.0)
    op.Set(Gf.Vec3d(0, 0, -3), 1.0)
    op.Set(Gf.Vec3d(0, 0, -3000), 2.0)
    stage.GetRootLayer().Save()
    r = wb.Renderer(path, resolution=(160, 120), settings=wb.RenderSettings(method="analytic", aovs=()))
    stats = [r.render(f).stats for f in (0.0, 0.0, 2.0, 0.0)]
    assert [st["triangles"] for st in stats] == [1280, 1280, 20, 1280]
    assert [st["prims_reused"] for st in stats] == [0, 1, 0, 0]   # kept at one level, read again at another

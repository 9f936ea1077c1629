"""Batched xformOp transforms (usd/xform_ops.py) against UsdGeom.XformCache, the oracle: random op
stacks of every supported kind, animated between samples outside the window, at many times."""

import os

import numpy as np
import pytest
from pxr import Gf, Usd, UsdGeom

from warp_blur.usd.xform_ops import LinearTransforms

P = UsdGeom.XformOp.PrecisionDouble
F = UsdGeom.XformOp.PrecisionFloat


def _random_stack(xf: UsdGeom.Xformable, rng: np.random.Generator, precision) -> None:
    """Three to six ops of random kinds (all but orient, which USD places), each sampled at times 0
    and 10, or 0, 5 and 10 (or held)."""
    kinds = ["translate", "scale", "rotateX", "rotateY", "rotateZ", "rotateXYZ", "rotateZYX", "rotateYXZ",
             "transform", "translateX", "scaleZ", "pivot"]
    for n, kind in enumerate(rng.choice(kinds, size=rng.integers(3, 7))):
        suffix = f"s{n}"
        animated = rng.random() < 0.8
        times = (0.0, 5.0, 10.0) if rng.random() < 0.5 else (0.0, 10.0)   # 5: inside the widest window
        if kind == "pivot":
            op = xf.AddTranslateOp(precision, suffix)
            op.Set(Gf.Vec3d(*rng.normal(size=3)) if precision == P else Gf.Vec3f(*rng.normal(size=3)))
            continue
        if kind == "transform":
            op = xf.AddTransformOp(P, suffix)
            for t in times if animated else (0.0,):
                m = Gf.Matrix4d(1.0)
                m.SetRotate(Gf.Rotation(Gf.Vec3d(*rng.normal(size=3)), float(rng.uniform(-180, 180))))
                m.SetTranslateOnly(Gf.Vec3d(*rng.normal(size=3)))
                op.Set(m, t)
            continue
        add = {"translate": xf.AddTranslateOp, "scale": xf.AddScaleOp, "rotateX": xf.AddRotateXOp,
               "rotateY": xf.AddRotateYOp, "rotateZ": xf.AddRotateZOp, "rotateXYZ": xf.AddRotateXYZOp,
               "rotateZYX": xf.AddRotateZYXOp, "rotateYXZ": xf.AddRotateYXZOp,
               "translateX": xf.AddTranslateXOp, "scaleZ": xf.AddScaleZOp}[kind]
        op = add(precision, suffix)
        scalar = kind in ("rotateX", "rotateY", "rotateZ", "translateX", "scaleZ")
        for t in times if animated else (0.0,):
            v = rng.uniform(0.5, 2.0, size=3) if kind.startswith("scale") else rng.uniform(-200, 200, size=3)
            if scalar:
                op.Set(float(v[0]), t)
            else:
                op.Set(Gf.Vec3d(*v) if precision == P else Gf.Vec3f(*v), t)
    # a pivot's inverse, as USD's common API writes one
    pivots = [op for op in xf.GetOrderedXformOps() if op.GetOpType() == UsdGeom.XformOp.TypeTranslate
              and not op.GetAttr().ValueMightBeTimeVarying()]
    if pivots:
        xf.AddTranslateOp(precision, pivots[0].GetOpName().split(":")[-1], isInverseOp=True)


@pytest.mark.parametrize("lo,hi", [(4.25, 4.75), (0.0, 10.0), (-1.0, 0.0)])
@pytest.mark.parametrize("precision,rtol", [(P, 1e-11), (F, 3e-6)])
def test_batched_transforms_equal_usdgeoms_at_every_time(precision, rtol, lo, hi):
    rng = np.random.default_rng(7)
    stage = Usd.Stage.CreateInMemory()
    parent = UsdGeom.Xform.Define(stage, "/Parent")
    parent.AddTranslateOp().Set(Gf.Vec3d(3, -2, 1))
    parent.AddRotateYOp().Set(30.0)
    prims = []
    for i in range(60):
        path = f"/Parent/P{i}" if i % 3 else f"/Root{i}"
        xf = UsdGeom.Xform.Define(stage, path)
        _random_stack(xf, rng, precision)
        prims.append(xf.GetPrim())
        if i % 4 == 0:   # a gprim under an animated Xform: its parent's ops are its motion
            prims.append(UsdGeom.Cube.Define(stage, f"{path}/Cube").GetPrim())
        elif i % 4 == 1:   # a scope between, then a child with its own animated ops
            stage.DefinePrim(f"{path}/Scope", "Scope")
            child = UsdGeom.Xform.Define(stage, f"{path}/Scope/Child")
            _random_stack(child, rng, precision)
            prims.append(child.GetPrim())
    batch = LinearTransforms(prims, lo, hi, {}, UsdGeom.XformCache(Usd.TimeCode(lo)))
    assert batch.placed.all()
    assert len(batch.batches) > 10   # many signatures, each its own pass
    for t in np.linspace(lo, hi, 7):
        out = np.zeros((len(prims), 4, 4))
        batch.at(t, out)
        cache = UsdGeom.XformCache(Usd.TimeCode(t))
        expected = np.array([np.array(cache.GetLocalToWorldTransform(p)) for p in prims])
        scale = np.abs(expected).max(axis=(1, 2), keepdims=True)
        np.testing.assert_allclose(out / scale, expected / scale, rtol=0, atol=rtol)


def test_samples_inside_the_window_are_followed_and_the_rest_left_to_usd():
    stage = Usd.Stage.CreateInMemory()
    inside = UsdGeom.Xform.Define(stage, "/Inside")            # samples inside the window
    op = inside.AddTranslateOp()
    for t, x in ((0.0, 0.0), (4.4, 5.0), (4.5, -2.0), (4.6, 3.0), (10.0, 0.0)):
        op.Set(Gf.Vec3d(x, 0, 0), t)
    moving_parent = UsdGeom.Xform.Define(stage, "/Moving")     # an animated parent, sampled inside
    op = moving_parent.AddRotateXYZOp()
    for t, r in ((0.0, (0, 0, 0)), (4.45, (30, -20, 5)), (10.0, (90, 0, 180))):
        op.Set(Gf.Vec3f(*r), t)
    child = UsdGeom.Xform.Define(stage, "/Moving/Child")
    child.AddRotateZOp().Set(10.0, 0.0)
    child.GetOrderedXformOps()[0].Set(20.0, 10.0)
    singular = UsdGeom.Xform.Define(stage, "/Singular")         # an inverse scale: USD's call
    scale = singular.AddScaleOp(opSuffix="s")
    scale.Set(Gf.Vec3f(1, 1, 1), 0.0)
    scale.Set(Gf.Vec3f(0, 2, 2), 10.0)
    singular.AddScaleOp(opSuffix="s", isInverseOp=True)
    unread = UsdGeom.Xform.Define(stage, "/Unread")             # an op with no value
    unread.AddTranslateOp().Set(Gf.Vec3d(1, 0, 0), 0.0)
    unread.GetOrderedXformOps()[0].Set(Gf.Vec3d(2, 0, 0), 10.0)
    unread.AddRotateXOp()
    near = UsdGeom.Xform.Define(stage, "/Orient")              # orient: USD's own (module docstring)
    op = near.AddOrientOp()
    op.Set(Gf.Quatf(1, 0, 0, 0), 0.0)
    op.Set(Gf.Quatf(0.99999309, 0, 0, -0.00372818), 1.0)      # InterpolationTest.usdz's first key
    prims = [p.GetPrim() for p in (inside, child, singular, unread, near)]
    batch = LinearTransforms(prims, 4.25, 4.75, {}, UsdGeom.XformCache(Usd.TimeCode(4.5)))
    assert batch.placed.tolist() == [True, True, False, False, False]
    assert batch.breakpoints.tolist() == [4.25, 4.4, 4.45, 4.5, 4.6, 4.75]
    for t in (4.25, 4.3, 4.4, 4.42, 4.45, 4.5, 4.55, 4.6, 4.7, 4.75):
        out = np.full((5, 4, 4), 7.0)
        batch.at(t, out)
        assert (out[2:] == 7.0).all()   # rows it did not place are left alone
        cache = UsdGeom.XformCache(Usd.TimeCode(t))
        for i in (0, 1):
            np.testing.assert_allclose(out[i], np.array(cache.GetLocalToWorldTransform(prims[i])), atol=1e-6)
    stage.SetInterpolationType(Usd.InterpolationTypeHeld)   # values step at samples: none is linear
    assert not LinearTransforms(prims, 4.25, 4.75, {}, UsdGeom.XformCache(Usd.TimeCode(4.5))).placed.any()
    stage.SetInterpolationType(Usd.InterpolationTypeLinear)
    crowded = UsdGeom.Xform.Define(stage, "/Crowded").AddTranslateXOp()   # more samples than it follows
    for i in range(40):
        crowded.Set(float(i % 3), 4.26 + i * 0.01)
    assert not LinearTransforms([stage.GetPrimAtPath("/Crowded")], 4.25, 4.75, {},
                                UsdGeom.XformCache(Usd.TimeCode(4.5))).placed.any()


@pytest.mark.parametrize("method", ["analytic", "accumulation"])
def test_a_render_of_animated_props_is_the_same_batched_or_prim_by_prim(tmp_path, monkeypatch, method):
    """Forty cubes under animated Xforms (translate and turn): the frame rendered with the batched
    transforms equals the one rendered asking USD prim by prim (float32 rounding at most)."""
    import sys

    import warp_blur as wb
    import warp_blur.usd.units as units
    sys.path.insert(0, str(__import__("pathlib").Path(__file__).resolve().parents[1] / "bench"))
    from bench_props import make_props
    path = make_props(str(tmp_path / "props.usda"), 40)
    settings = wb.RenderSettings(method=method, samples=8, aovs=())
    batched = wb.Renderer(path, resolution=(64, 48), settings=settings).render(3.0).rgba
    monkeypatch.setattr(units, "BATCH_XFORM_OPS", False)
    alone = wb.Renderer(path, resolution=(64, 48), settings=settings).render(3.0).rgba
    assert batched[..., 3].sum() > 100   # the props are in view
    np.testing.assert_allclose(batched, alone, rtol=0, atol=1e-5)


INTERPOLATION_TEST = os.path.join(os.path.dirname(__file__), "..", "..", "shared", "real_usd", "test_assets", "USDZ",
                                  "InterpolationTest", "InterpolationTest.usdz")


@pytest.mark.parametrize("scene", [INTERPOLATION_TEST,
                                   os.path.join(os.path.dirname(__file__), "..", "usd_scenes", "deep_overlap.usda")])
def test_snapshots_of_real_animation_are_the_same_batched_or_prim_by_prim(monkeypatch, scene):
    """A glTF export's keys (InterpolationTest.usdz: linear, step and spline channels baked to
    samples, orient among them, which found the quaternion case the module leaves to USD) and
    deep_overlap's layers: every snapshot's positions as placing each prim through USD gives them
    (float ops: to float32 rounding)."""
    if not os.path.exists(scene):
        pytest.skip("../shared/real_usd is not beside the checkout")
    import warp_blur.usd.units as units
    from warp_blur.usd.scene import Scene
    from warp_blur.usd.stage import Shutter, choose_camera, open_stage
    stage = open_stage(scene)
    cam = choose_camera(stage, None)
    batched_prims = 0
    for frame in np.linspace(stage.GetStartTimeCode(), stage.GetEndTimeCode(), 4):
        positions = {}
        for batched in (True, False):
            monkeypatch.setattr(units, "BATCH_XFORM_OPS", batched)
            scene_ = Scene(stage, cam, float(frame), Shutter(float(frame) - 0.5, float(frame) + 0.5))
            positions[batched] = np.stack([scene_.snapshot(float(frame) + u).positions for u in np.linspace(-0.5, 0.5, 7)])
            if batched:
                batched_prims += sum(len(g.linear[0]) for g in scene_._small_unit_groups() if g.linear is not None)
        size = np.abs(positions[False]).max()
        np.testing.assert_allclose(positions[True] / size, positions[False] / size, rtol=0, atol=1e-6)
    assert batched_prims > 0

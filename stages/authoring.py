"""Small helpers for authoring the animated test and demo stages (used by stages/make_*.py and tests).

Everything written is deterministic: the same call writes the same .usda text.
"""

from __future__ import annotations

import math
from typing import Sequence

from pxr import Gf, Sdf, Usd, UsdGeom, UsdLux, UsdShade, Vt


def new_stage(path: str, start: float = 0, end: float = 2, fps: float = 24, up: str = "Y",
              meters_per_unit: float = 1.0, doc: str = "") -> Usd.Stage:
    stage = Usd.Stage.CreateNew(path)
    stage.SetStartTimeCode(start)
    stage.SetEndTimeCode(end)
    stage.SetFramesPerSecond(fps)
    stage.SetTimeCodesPerSecond(fps)
    UsdGeom.SetStageUpAxis(stage, UsdGeom.Tokens.y if up == "Y" else UsdGeom.Tokens.z)
    UsdGeom.SetStageMetersPerUnit(stage, meters_per_unit)
    world = UsdGeom.Xform.Define(stage, "/World")
    stage.SetDefaultPrim(world.GetPrim())
    if doc:
        stage.GetRootLayer().documentation = doc
    return stage


def _set_samples(attr: Usd.Attribute, samples: dict | None, value=None) -> None:
    if samples:
        for t in sorted(samples):
            attr.Set(samples[t], Usd.TimeCode(t))
    elif value is not None:
        attr.Set(value)


def add_xform_ops(xformable: UsdGeom.Xformable, translate=None, translate_samples: dict | None = None,
                  rotate_axis: str | None = None, rotate_samples: dict | None = None, rotate=None,
                  scale=None) -> None:
    """translate, then rotate about one axis (degrees), then scale (USD op order)."""
    if translate is not None or translate_samples:
        op = xformable.AddTranslateOp()
        _set_samples(op.GetAttr(), {t: Gf.Vec3d(*v) for t, v in (translate_samples or {}).items()},
                     Gf.Vec3d(*translate) if translate is not None else None)
    if rotate_axis:
        op = {"X": xformable.AddRotateXOp, "Y": xformable.AddRotateYOp, "Z": xformable.AddRotateZOp}[rotate_axis]()
        _set_samples(op.GetAttr(), rotate_samples, rotate if rotate is not None else 0.0)
    if scale is not None:
        xformable.AddScaleOp().Set(Gf.Vec3f(*scale))


def add_camera(stage: Usd.Stage, path: str = "/World/Cam", translate=(0, 0, 10), translate_samples=None,
               rotate_axis=None, rotate_samples=None, shutter=(-0.5, 0.5), focal=24.0, haperture=24.0,
               vaperture=18.0, clipping=(0.1, 1000.0), projection="perspective", hoffset=0.0,
               voffset=0.0) -> UsdGeom.Camera:
    cam = UsdGeom.Camera.Define(stage, path)
    cam.CreateFocalLengthAttr(focal)
    cam.CreateHorizontalApertureAttr(haperture)
    cam.CreateVerticalApertureAttr(vaperture)
    cam.CreateHorizontalApertureOffsetAttr(hoffset)
    cam.CreateVerticalApertureOffsetAttr(voffset)
    cam.CreateClippingRangeAttr(Gf.Vec2f(*clipping))
    cam.CreateProjectionAttr(projection)
    if shutter is not None:
        cam.CreateShutterOpenAttr(shutter[0])
        cam.CreateShutterCloseAttr(shutter[1])
    add_xform_ops(cam, translate=translate if not translate_samples else None,
                  translate_samples=translate_samples, rotate_axis=rotate_axis, rotate_samples=rotate_samples)
    return cam


def add_material(stage: Usd.Stage, path: str, diffuse=(0.0, 0.0, 0.0), emissive=(0.0, 0.0, 0.0),
                 specular=(0.0, 0.0, 0.0), roughness=1.0, metallic=0.0, specular_workflow=True) -> UsdShade.Material:
    """A UsdPreviewSurface; the defaults make an emissive-only (shading-independent) material."""
    mat = UsdShade.Material.Define(stage, path)
    sh = UsdShade.Shader.Define(stage, f"{path}/PreviewSurface")
    sh.CreateIdAttr("UsdPreviewSurface")
    sh.CreateInput("diffuseColor", Sdf.ValueTypeNames.Color3f).Set(Gf.Vec3f(*diffuse))
    sh.CreateInput("emissiveColor", Sdf.ValueTypeNames.Color3f).Set(Gf.Vec3f(*emissive))
    sh.CreateInput("specularColor", Sdf.ValueTypeNames.Color3f).Set(Gf.Vec3f(*specular))
    sh.CreateInput("roughness", Sdf.ValueTypeNames.Float).Set(roughness)
    sh.CreateInput("metallic", Sdf.ValueTypeNames.Float).Set(metallic)
    sh.CreateInput("useSpecularWorkflow", Sdf.ValueTypeNames.Int).Set(1 if specular_workflow else 0)
    sh.CreateInput("opacity", Sdf.ValueTypeNames.Float).Set(1.0)
    mat.CreateSurfaceOutput().ConnectToSource(sh.ConnectableAPI(), "surface")
    return mat


def add_textured_material(stage: Usd.Stage, path: str, image: str, input_name: str = "emissiveColor",
                          color_space: str = "raw", wrap: str = "clamp", st_name: str = "st",
                          output: str = "rgb") -> UsdShade.Material:
    """A UsdPreviewSurface whose `input_name` reads output `output` (rgb, r, g, b, a) of a
    UsdUVTexture of `image` (a path relative to the stage), at texture coordinates from primvar
    `st_name`; black otherwise."""
    mat = add_material(stage, path)
    surface = UsdShade.Shader.Get(stage, f"{path}/PreviewSurface")
    reader = UsdShade.Shader.Define(stage, f"{path}/StReader")
    reader.CreateIdAttr("UsdPrimvarReader_float2")
    reader.CreateInput("varname", Sdf.ValueTypeNames.Token).Set(st_name)
    tex = UsdShade.Shader.Define(stage, f"{path}/Texture")
    tex.CreateIdAttr("UsdUVTexture")
    tex.CreateInput("file", Sdf.ValueTypeNames.Asset).Set(image)
    tex.CreateInput("sourceColorSpace", Sdf.ValueTypeNames.Token).Set(color_space)
    tex.CreateInput("wrapS", Sdf.ValueTypeNames.Token).Set(wrap)
    tex.CreateInput("wrapT", Sdf.ValueTypeNames.Token).Set(wrap)
    tex.CreateInput("st", Sdf.ValueTypeNames.Float2).ConnectToSource(reader.ConnectableAPI(), "result")
    out_type = Sdf.ValueTypeNames.Float3 if output == "rgb" else Sdf.ValueTypeNames.Float
    tex.CreateOutput(output, out_type)
    surface.GetInput(input_name).ConnectToSource(tex.ConnectableAPI(), output)
    return mat


def set_st(mesh: UsdGeom.Mesh, st: Sequence, interpolation: str = "vertex", name: str = "st") -> None:
    """Texture coordinates as a texCoord2f primvar."""
    pv = UsdGeom.PrimvarsAPI(mesh).CreatePrimvar(name, Sdf.ValueTypeNames.TexCoord2fArray, interpolation)
    pv.Set(Vt.Vec2fArray([Gf.Vec2f(*uv) for uv in st]))


def bind(prim: Usd.Prim, material: UsdShade.Material | None) -> None:
    if material is not None:
        UsdShade.MaterialBindingAPI.Apply(prim).Bind(material)


def add_mesh(stage: Usd.Stage, path: str, points: Sequence, counts: Sequence[int], indices: Sequence[int],
             material=None, color=(0.5, 0.5, 0.5), double_sided=True, points_samples: dict | None = None,
             **xform) -> UsdGeom.Mesh:
    mesh = UsdGeom.Mesh.Define(stage, path)
    mesh.CreateFaceVertexCountsAttr(list(counts))
    mesh.CreateFaceVertexIndicesAttr(list(indices))
    mesh.CreateSubdivisionSchemeAttr(UsdGeom.Tokens.none)
    mesh.CreateDoubleSidedAttr(double_sided)
    pts_attr = mesh.CreatePointsAttr()
    if points_samples:
        for t in sorted(points_samples):
            pts_attr.Set(Vt.Vec3fArray([Gf.Vec3f(*p) for p in points_samples[t]]), Usd.TimeCode(t))
    else:
        pts_attr.Set(Vt.Vec3fArray([Gf.Vec3f(*p) for p in points]))
    mesh.CreateDisplayColorAttr([Gf.Vec3f(*color)])
    add_xform_ops(mesh, **xform)
    bind(mesh.GetPrim(), material)
    return mesh


def add_quad(stage: Usd.Stage, path: str, half_w: float, half_h: float, **kw) -> UsdGeom.Mesh:
    pts = [(-half_w, -half_h, 0), (half_w, -half_h, 0), (half_w, half_h, 0), (-half_w, half_h, 0)]
    return add_mesh(stage, path, pts, [4], [0, 1, 2, 3], **kw)


def grid(nx: int, ny: int, width: float, height: float, z_fn=None, t: float = 0.0):
    """Points and quad topology of an nx×ny-cell grid in the XY plane (z from z_fn(x, y, t))."""
    pts = []
    for j in range(ny + 1):
        for i in range(nx + 1):
            x = -width / 2 + width * i / nx
            y = -height / 2 + height * j / ny
            pts.append((x, y, z_fn(x, y, t) if z_fn else 0.0))
    idx = []
    for j in range(ny):
        for i in range(nx):
            a = j * (nx + 1) + i
            idx += [a, a + 1, a + nx + 2, a + nx + 1]
    return pts, [4] * (nx * ny), idx


def add_dome(stage: Usd.Stage, color=(0.1, 0.12, 0.2), intensity=1.0, path="/World/Dome") -> UsdLux.DomeLight:
    dome = UsdLux.DomeLight.Define(stage, path)
    dome.CreateColorAttr(Gf.Vec3f(*color))
    dome.CreateIntensityAttr(intensity)
    return dome


def add_distant_light(stage: Usd.Stage, path: str, intensity=1.0, color=(1, 1, 1), rotate=(-45, 30, 0),
                      shadows=True) -> UsdLux.DistantLight:
    light = UsdLux.DistantLight.Define(stage, path)
    light.CreateIntensityAttr(intensity)
    light.CreateNormalizeAttr(True)   # intensity is the illuminance (UsdLux), whatever the sun's angle
    light.CreateColorAttr(Gf.Vec3f(*color))
    light.AddRotateXYZOp().Set(Gf.Vec3f(*rotate))
    UsdLux.ShadowAPI.Apply(light.GetPrim()).CreateShadowEnableAttr(shadows)
    return light


def add_sphere_light(stage: Usd.Stage, path: str, radius=0.2, intensity=10.0, color=(1, 1, 1), translate=(0, 3, 0),
                     translate_samples=None, shadows=True) -> UsdLux.SphereLight:
    light = UsdLux.SphereLight.Define(stage, path)
    light.CreateRadiusAttr(radius)
    light.CreateIntensityAttr(intensity)
    light.CreateColorAttr(Gf.Vec3f(*color))
    UsdLux.ShadowAPI.Apply(light.GetPrim()).CreateShadowEnableAttr(shadows)
    add_xform_ops(light, translate=None if translate_samples else translate, translate_samples=translate_samples)
    return light


def orbit(radius: float, turns: float, frames: Sequence[float], height: float = 0.0, phase: float = 0.0) -> dict:
    """Translate samples on a circle in the XZ plane."""
    out = {}
    n = len(frames) - 1
    for k, f in enumerate(frames):
        a = phase + 2 * math.pi * turns * k / max(n, 1)
        out[f] = (radius * math.cos(a), height, radius * math.sin(a))
    return out


def sphere_field(path: str, spheres: int) -> str:
    """`spheres` spheres of radius 0.3 scattered 2-110 units in front of a wide camera, at heights
    0.3-3 over a ground, half of them drifting (a random velocity, 10 position samples), a sun
    with shadows and a dome (tests/test_tessellate.py and bench/bench_particles.py)."""
    import numpy as np
    stage = new_stage(path, end=10)
    add_camera(stage, translate=(0, 4, 12), shutter=(-0.25, 0.25), focal=18.0)
    add_dome(stage)
    add_distant_light(stage, "/World/Sun", intensity=2.5)
    ground = UsdGeom.Mesh.Define(stage, "/World/Ground")
    ground.CreatePointsAttr([(-60, 0, -120), (60, 0, -120), (60, 0, 20), (-60, 0, 20)])
    ground.CreateFaceVertexCountsAttr([4])
    ground.CreateFaceVertexIndicesAttr([0, 3, 2, 1])
    field = UsdGeom.PointInstancer.Define(stage, "/World/Field")
    ball = UsdGeom.Sphere.Define(stage, "/World/Field/Protos/Ball")
    ball.CreateRadiusAttr(0.3)
    UsdShade.MaterialBindingAPI.Apply(ball.GetPrim()).Bind(
        add_material(stage, "/World/Looks/Ball", diffuse=(0.8, 0.3, 0.2)))
    field.CreatePrototypesRel().SetTargets([ball.GetPath()])
    rng = np.random.default_rng(1)
    z = 8.0 - rng.uniform(0, 110, spheres)
    pos = np.c_[rng.uniform(-1, 1, spheres) * (8 - z) * 0.5, rng.uniform(0.3, 3.0, spheres), z]
    vel = np.where(rng.random((spheres, 1)) < 0.5, rng.normal(0, 1.5, (spheres, 3)), 0.0)
    for f in range(0, 11):
        field.GetPositionsAttr().Set(Vt.Vec3fArray.FromNumpy((pos + vel * f).astype(np.float32)), float(f))
    field.CreateProtoIndicesAttr(Vt.IntArray.FromNumpy(np.zeros(spheres, np.int32)))
    stage.GetRootLayer().Save()
    return path

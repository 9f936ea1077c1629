"""The emissive variant of a bench stage that every peer renders (bench/bench_peers.py), written so
that Blender's USD importer reads the same geometry and motion warp_blur does.

Conversions, each the same input for every renderer: UsdPreviewSurfaces emit emissiveColor +
diffuseColor (black diffuse and specular); lights other than the dome are removed; a Cube becomes
its 6-quad Mesh (the importer drops the Cube's material); subdivision meshes become their control
cage (warp_blur's refinement and Blender's modifier differ); a PointInstancer's velocities and
angular velocities are baked into time samples at the frame's shutter open and close (the importer
does not carry them), so positions move linearly and orientations slerp between the two.
"""

from __future__ import annotations

from pxr import Gf, Sdf, Usd, UsdGeom, UsdLux, UsdShade

_CUBE_POINTS = [(-1, -1, -1), (1, -1, -1), (1, 1, -1), (-1, 1, -1), (-1, -1, 1), (1, -1, 1), (1, 1, 1), (-1, 1, 1)]
_CUBE_QUADS = [0, 3, 2, 1, 4, 5, 6, 7, 0, 1, 5, 4, 2, 3, 7, 6, 1, 2, 6, 5, 0, 4, 7, 3]


def emissive_variant(src: str, dst: str, frame: float) -> tuple[float, float, float]:
    """Write the emissive variant of stage src, for rendering `frame`, to dst; returns the dome's
    radiance (black if none)."""
    out = Usd.Stage.Open(Usd.Stage.Open(src).Flatten())
    dome = (0.0, 0.0, 0.0)
    for prim in list(out.Traverse()):
        if prim.IsA(UsdLux.DomeLight):
            light = UsdLux.DomeLight(prim)
            c = light.GetColorAttr().Get()
            k = light.GetIntensityAttr().Get() * 2.0 ** light.GetExposureAttr().Get()
            dome = tuple(float(v) * k for v in c)
        elif prim.HasAPI(UsdLux.LightAPI):
            out.RemovePrim(prim.GetPath())
            continue
        if prim.IsA(UsdGeom.Cube):
            _cube_as_mesh(prim)
        if prim.IsA(UsdGeom.Mesh):
            UsdGeom.Mesh(prim).GetSubdivisionSchemeAttr().Set(UsdGeom.Tokens.none)
        if prim.IsA(UsdGeom.PointInstancer):
            _bake_instancer_motion(UsdGeom.PointInstancer(prim), out, frame)
        shader = UsdShade.Shader(prim)
        if shader and shader.GetIdAttr().Get() == "UsdPreviewSurface":
            def colour(name, fallback):
                inp = shader.GetInput(name)
                value = inp.Get() if inp else None
                return Gf.Vec3f(*(value if value is not None else fallback))
            shader.CreateInput("emissiveColor", Sdf.ValueTypeNames.Color3f).Set(
                colour("emissiveColor", (0, 0, 0)) + colour("diffuseColor", (0.18, 0.18, 0.18)))
            shader.CreateInput("diffuseColor", Sdf.ValueTypeNames.Color3f).Set(Gf.Vec3f(0, 0, 0))
            shader.CreateInput("specularColor", Sdf.ValueTypeNames.Color3f).Set(Gf.Vec3f(0, 0, 0))
            shader.CreateInput("useSpecularWorkflow", Sdf.ValueTypeNames.Int).Set(1)
            shader.CreateInput("metallic", Sdf.ValueTypeNames.Float).Set(0.0)
    out.GetRootLayer().Export(dst)
    return dome


def _cube_as_mesh(prim) -> None:
    """Turn a (static-size) Cube prim into the Mesh of its 6 faces, keeping xform ops and binding."""
    half = 0.5 * float(UsdGeom.Cube(prim).GetSizeAttr().Get())
    prim.RemoveProperty("size")
    prim.RemoveProperty("extent")
    prim.SetTypeName("Mesh")
    mesh = UsdGeom.Mesh(prim)
    mesh.CreatePointsAttr([Gf.Vec3f(*(half * c for c in p)) for p in _CUBE_POINTS])
    mesh.CreateFaceVertexCountsAttr([4] * 6)
    mesh.CreateFaceVertexIndicesAttr(_CUBE_QUADS)


def _bake_instancer_motion(inst: UsdGeom.PointInstancer, stage: Usd.Stage, frame: float) -> None:
    """Replace a PointInstancer's velocities by positions/orientations sampled at shutter open and
    close of `frame` (ComputeInstanceTransformsAtTimes, so USD's own motion rules decide)."""
    if not (inst.GetVelocitiesAttr().HasAuthoredValue() or inst.GetAngularVelocitiesAttr().HasAuthoredValue()):
        return
    cam = next((UsdGeom.Camera(p) for p in stage.Traverse() if p.IsA(UsdGeom.Camera)), None)
    shutter = (cam.GetShutterOpenAttr().Get(), cam.GetShutterCloseAttr().Get()) if cam else (0.0, 0.0)
    times = [Usd.TimeCode(frame + s) for s in shutter]
    xforms = inst.ComputeInstanceTransformsAtTimes(times, Usd.TimeCode(frame),
                                                   UsdGeom.PointInstancer.IncludeProtoXform,
                                                   UsdGeom.PointInstancer.ApplyMask)
    scales = inst.GetScalesAttr().Get(frame)
    positions, orients = inst.GetPositionsAttr(), inst.GetOrientationsAttr()
    for attr in (positions, orients, inst.GetVelocitiesAttr(), inst.GetAngularVelocitiesAttr(),
                 inst.GetAccelerationsAttr()):
        attr.Clear()
    for time, mats in zip(times, xforms):
        pos, rot = [], []
        for i, m in enumerate(mats):
            pos.append(Gf.Vec3f(m.ExtractTranslation()))
            s = scales[i] if scales else Gf.Vec3f(1, 1, 1)
            r = Gf.Matrix3d(*[m[row][col] / s[row] for row in range(3) for col in range(3)])
            rot.append(Gf.Quath(r.ExtractRotation().GetQuat()))
        positions.Set(pos, time)
        orients.Set(rot, time)

"""Small stages built by tests (written to tmp paths with the stages/ authoring helpers)."""

from __future__ import annotations

import math

from authoring import add_camera, add_dome, add_distant_light, add_material, add_mesh, add_quad, new_stage


def emissive_quad_stage(path: str, translate_samples=None, translate=(0, 0, 0), shutter=(-0.5, 0.5),
                        half=1.0, emissive=(0.9, 0.4, 0.2), dome=(0.1, 0.12, 0.2), with_light=False,
                        rotate_axis=None, rotate_samples=None, camera=None) -> str:
    stage = new_stage(path)
    add_camera(stage, shutter=shutter, **(camera or {}))
    if dome is not None:
        add_dome(stage, dome)
    if with_light:
        add_distant_light(stage, "/World/Sun", intensity=5.0)
    mat = add_material(stage, "/World/Looks/Emit", emissive=emissive)
    add_quad(stage, "/World/Quad", half, half, material=mat,
             translate=None if translate_samples else translate, translate_samples=translate_samples,
             rotate_axis=rotate_axis, rotate_samples=rotate_samples)
    stage.GetRootLayer().Save()
    return path


def two_quads_stage(path: str) -> str:
    """A near quad moving right in front of a far quad moving left (the occluder case)."""
    stage = new_stage(path)
    add_camera(stage)
    add_dome(stage)
    a = add_material(stage, "/World/Looks/A", emissive=(0.2, 0.4, 1.0))
    b = add_material(stage, "/World/Looks/B", emissive=(1.0, 0.9, 0.2))
    add_quad(stage, "/World/Far", 2.0, 1.5, material=a, translate_samples={0.5: (2, 0, -3), 1.5: (-1, 0, -3)})
    add_quad(stage, "/World/Near", 0.6, 0.6, material=b, translate_samples={0.5: (-2.5, 0.2, 2), 1.5: (1.5, 0.2, 2)})
    stage.GetRootLayer().Save()
    return path


def lit_stage(path: str, shutter=(-0.25, 0.25)) -> str:
    """A grey lit quad under a distant light, static, and a moving lit triangle."""
    stage = new_stage(path)
    add_camera(stage, shutter=shutter)
    add_distant_light(stage, "/World/Sun", intensity=2.0, rotate=(-30, 20, 0))
    grey = add_material(stage, "/World/Looks/Grey", diffuse=(0.5, 0.5, 0.5), roughness=0.5, specular=(0.04,) * 3)
    add_quad(stage, "/World/Back", 3.0, 2.0, material=grey, translate=(0, 0, -2))
    add_mesh(stage, "/World/Tri", [(-0.8, -0.6, 0), (0.9, -0.4, 0), (0.1, 0.9, 0)], [3], [0, 1, 2],
             material=grey, translate_samples={0.5: (-1.5, 0.0, 0.0), 1.5: (1.5, 0.3, 0.0)})
    stage.GetRootLayer().Save()
    return path


def moving_layers_stage(path: str, layers: int, cross: bool = False, size: float = 1.2) -> str:
    """`layers` emissive quads stacked in depth over the same pixels, each moving; with cross=True
    their depths reverse order during the shutter (every pair crosses in depth-time)."""
    import colorsys
    stage = new_stage(path)
    add_camera(stage)
    add_dome(stage)
    for i in range(layers):
        rgb = colorsys.hsv_to_rgb(i / layers, 0.8, 0.9)
        mat = add_material(stage, f"/World/Looks/L{i}", emissive=rgb)
        z0 = -0.02 * i
        z1 = -0.02 * (layers - 1 - i) if cross else z0
        dx = 0.3 * ((i % 5) - 2) / 2
        add_quad(stage, f"/World/L{i}", size, size, material=mat,
                 translate_samples={0.5: (-dx - 0.2, 0.05 * (i % 3), z0), 1.5: (dx + 0.2, -0.05 * (i % 3), z1)})
    stage.GetRootLayer().Save()
    return path


def shadow_stage(path: str, occluder_samples=None, occluder_at=(-0.6, 1.0, 0.0), light: str = "distant",
                 light_samples=None, shadows: bool = True, mover: bool = False, light_size: float = 0.0,
                 camera_samples=None) -> str:
    """A lit grey ground seen from above at 45°, an emissive horizontal square occluder above it
    (translating with `occluder_samples`, frame -> position), one light straight overhead
    ("distant", "sphere" (radius light_size) or "rect" (side light_size), moving with
    `light_samples`), optionally a second small occluder moving elsewhere (`mover`) and a moving
    camera (`camera_samples`)."""
    from authoring import add_sphere_light, add_xform_ops
    from pxr import UsdLux
    stage = new_stage(path)
    add_camera(stage, translate=None if camera_samples else (0.0, 4.0, 4.0), translate_samples=camera_samples,
               rotate_axis="X", rotate_samples={0: -45.0})
    grey = add_material(stage, "/World/Looks/Grey", diffuse=(0.8, 0.8, 0.8), roughness=1.0)
    dark = add_material(stage, "/World/Looks/Dark", emissive=(0.05, 0.05, 0.05))
    add_mesh(stage, "/World/Ground", [(-2.5, 0, 2.5), (2.5, 0, 2.5), (2.5, 0, -2.5), (-2.5, 0, -2.5)], [4],
             [0, 1, 2, 3], material=grey)
    square = [(-0.4, 0, 0.4), (0.4, 0, 0.4), (0.4, 0, -0.4), (-0.4, 0, -0.4)]
    add_mesh(stage, "/World/Occluder", square, [4], [0, 1, 2, 3], material=dark,
             translate=None if occluder_samples else occluder_at, translate_samples=occluder_samples)
    if mover:
        add_mesh(stage, "/World/Mover", [(x * 0.5, y, z * 0.5) for x, y, z in square], [4], [0, 1, 2, 3],
                 material=dark, translate_samples={0.5: (1.3, 0.8, -0.6), 1.5: (1.3, 0.8, 0.6)})
    if light == "distant":
        add_distant_light(stage, "/World/Light", intensity=3.0, rotate=(-90, 0, 0), shadows=shadows)
    elif light == "sphere":
        add_sphere_light(stage, "/World/Light", radius=light_size, intensity=30.0, translate=(0, 3, 0),
                         translate_samples=light_samples, shadows=shadows)
    else:
        rect = UsdLux.RectLight.Define(stage, "/World/Light")
        rect.CreateWidthAttr(light_size)
        rect.CreateHeightAttr(light_size)
        rect.CreateIntensityAttr(30.0)
        UsdLux.ShadowAPI.Apply(rect.GetPrim()).CreateShadowEnableAttr(shadows)
        add_xform_ops(rect, translate=None if light_samples else (0, 3, 0), translate_samples=light_samples,
                      rotate_axis="X", rotate=-90.0)
    stage.GetRootLayer().Save()
    return path


def ramp_light_stage(path: str, intensity: dict | None = None) -> str:
    """A static grey quad under a distant light whose intensity ramps linearly over the shutter
    (radiance exactly linear in time; `intensity` maps frames to other time samples), half hidden
    for part of the shutter by an emissive quad sweeping in front of it."""
    stage = new_stage(path)
    add_camera(stage)
    add_dome(stage)
    sun = add_distant_light(stage, "/World/Sun", rotate=(-20, 10, 0), shadows=False)
    for frame, value in (intensity or {0.5: 0.5, 1.5: 4.0}).items():
        sun.GetIntensityAttr().Set(value, frame)
    grey = add_material(stage, "/World/Looks/Grey", diffuse=(0.6, 0.6, 0.6))
    emit = add_material(stage, "/World/Looks/Emit", emissive=(0.9, 0.3, 0.1))
    add_quad(stage, "/World/Back", 3.0, 2.0, material=grey, translate=(0, 0, -2))
    add_quad(stage, "/World/Sweep", 0.5, 2.5, material=emit, translate_samples={0.5: (-3.0, 0, 0), 1.5: (3.0, 0, 0)})
    stage.GetRootLayer().Save()
    return path


def translucent_layers_stage(path: str) -> str:
    """shadow_stage with nothing moving and three overlapping translucent (fractional opacity)
    squares at different heights above the lit ground, the occluder among them: under the light's
    one shadow map, only the squares' presence differs between instants."""
    from pxr import Sdf, Usd, UsdShade
    from authoring import add_material, add_mesh
    shadow_stage(path)
    stage = Usd.Stage.Open(path)
    surface = UsdShade.Shader.Get(stage, "/World/Looks/Dark/PreviewSurface")
    surface.GetInput("opacity").Set(0.5)
    surface.CreateInput("opacityThreshold", Sdf.ValueTypeNames.Float).Set(0.0)
    for i, (height, x, alpha) in enumerate([(0.6, -0.3, 0.4), (0.3, 0.1, 0.7)]):
        look = add_material(stage, f"/World/Looks/Glass{i}", diffuse=(0.2, 0.3 + 0.3 * i, 0.9), roughness=0.5)
        glass = UsdShade.Shader.Get(stage, f"/World/Looks/Glass{i}/PreviewSurface")
        glass.CreateInput("opacity", Sdf.ValueTypeNames.Float).Set(alpha)
        glass.CreateInput("opacityThreshold", Sdf.ValueTypeNames.Float).Set(0.0)
        add_mesh(stage, f"/World/Glass{i}", [(x - 0.6, height, 0.6), (x + 0.6, height, 0.6), (x + 0.6, height, -0.6),
                                            (x - 0.6, height, -0.6)], [4], [0, 1, 2, 3], material=look)
    stage.GetRootLayer().Save()
    return path


def lit_ball_stage(path: str, smooth: bool) -> str:
    """A lit icosphere (80 triangles, shared vertices) flying across the view with blur many
    pixels long: smooth (its cage with interpolated normals) or flat-shaded."""
    import trimesh
    from pxr import UsdGeom
    stage = new_stage(path)
    add_camera(stage)
    add_dome(stage, (0.08, 0.09, 0.12))
    add_distant_light(stage, "/World/Sun", intensity=2.5, rotate=(-40, 30, 0))
    mat = add_material(stage, "/World/Looks/Ball", diffuse=(0.55, 0.35, 0.25), roughness=0.5, specular=(0.04,) * 3)
    ico = trimesh.creation.icosphere(subdivisions=1, radius=2.0)
    mesh = add_mesh(stage, "/World/Ball", [tuple(map(float, v)) for v in ico.vertices], [3] * len(ico.faces),
                    [int(x) for x in ico.faces.ravel()], material=mat,
                    translate_samples={0.5: (-0.6, -0.1, 0.0), 1.5: (0.6, 0.15, 0.0)})
    if smooth:
        mesh.CreateSubdivisionSchemeAttr(UsdGeom.Tokens.catmullClark)
    stage.GetRootLayer().Save()
    return path


def tilted_layers_stage(path: str) -> str:
    """Moving, interpenetrating quads, every other one steeply tilted in depth (its nearest corner
    says little of its depth at a pixel) and the rest tilted by a few degrees (their corners lie
    within a percent or two of their depth anywhere: a walk that stopped a little early would
    miss them), plus, in front, two coplanar quads of different colours at the same place (a tie
    in depth at every pixel they cover)."""
    stage = new_stage(path)
    add_camera(stage)
    add_dome(stage)
    for i in range(10):
        mat = add_material(stage, f"/World/Looks/T{i}", emissive=(0.1 * i, 0.5, 1.0 - 0.1 * i))
        angle = math.radians((-70.0 + 15.0 * i) if i % 2 else (-4.0 + 1.0 * i))
        h = 1.5
        ax, az = h * math.cos(angle), h * math.sin(angle)

        def quad(shift: float, ax=ax, az=az, i=i) -> list:
            y0, y1 = -0.8 + 0.05 * i, 0.8 - 0.05 * i
            return [(-ax + shift, y0, -az), (ax + shift, y0, az), (ax + shift, y1, az), (-ax + shift, y1, -az)]
        add_mesh(stage, f"/World/T{i}", quad(0.0), [4], [0, 1, 2, 3], material=mat,
                 points_samples={0.5: quad(-0.3 + 0.06 * i), 1.5: quad(0.3 - 0.06 * i)})
    for name, colour in (("TwinA", (1.0, 0.0, 0.0)), ("TwinB", (0.0, 1.0, 0.0))):
        mat = add_material(stage, f"/World/Looks/{name}", emissive=colour)
        add_quad(stage, f"/World/{name}", 0.3, 0.3, material=mat, translate=(0.4, 0.3, 2.5))
    stage.GetRootLayer().Save()
    return path


def skimming_stage(path: str) -> str:
    """A still grey wall facing the camera at depth 10, with moving quads of other colours sliding
    across it just in front (0.1-0.8% nearer: a walk that gave up on moving entries a little
    before the still surface would miss them) and one just behind (never seen)."""
    stage = new_stage(path)
    add_camera(stage)
    add_dome(stage)
    wall = add_material(stage, "/World/Looks/Wall", emissive=(0.3, 0.3, 0.3))
    add_quad(stage, "/World/Wall", 3.0, 2.0, material=wall)
    for i, z in enumerate((0.01, 0.03, 0.05, 0.08, -0.02)):
        mat = add_material(stage, f"/World/Looks/S{i}", emissive=(1.0 - 0.2 * i, 0.2 * i, 0.5))
        y = -1.2 + 0.6 * i

        def quad(shift: float, y=y, z=z) -> list:
            return [(-0.5 + shift, y - 0.25, z), (0.5 + shift, y - 0.25, z), (0.5 + shift, y + 0.25, z),
                    (-0.5 + shift, y + 0.25, z)]
        add_mesh(stage, f"/World/S{i}", quad(0.0), [4], [0, 1, 2, 3], material=mat,
                 points_samples={0.5: quad(-0.8), 1.5: quad(0.8)})
    stage.GetRootLayer().Save()
    return path

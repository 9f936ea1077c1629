"""UsdPreviewSurface (through material binding) and displayColor into a flat material table.

Each row of the table (float32, MATERIAL_WIDTH columns) is read by `shading.py`:
diffuse rgb, emissive rgb, F0 rgb (specular reflectance at normal incidence), roughness,
use_corner_color (1 = diffuse comes from a colour primvar at the triangle's corners, displayColor
or the one a UsdPrimvarReader names), opacity; then the texture bindings of diffuse, emissive,
roughness, metallic and opacity (-1 none; see textures.py), the metallic-workflow flag, the
dielectric F0, metallic, opacityThreshold, a flag that the kernel must evaluate bindings and
the metallic mix per hit (then diffuse holds the raw diffuseColor), the binding of the
tangent-space `normal` map (-1 none), and a flag that roughness and metallic share one texture
sample (TextureSet.same_sample: glTF's metallic-roughness texture).
The specular F0 follows UsdPreviewSurface: specularColor in the specular workflow, else
lerp(((ior-1)/(ior+1))^2, diffuseColor, metallic) with the diffuse scaled by (1 - metallic).
Inputs connected to a UsdUVTexture (coordinates from a UsdPrimvarReader_float2) or, for the
diffuse colour, a UsdPrimvarReader_float3 are read; other connected nodes give USD's fallback,
with a warning.
"""

from __future__ import annotations

import math

from dataclasses import dataclass

import numpy as np
from pxr import Usd, UsdShade

from ..core.log import warn_once
from .textures import IDENTITY_ST, TextureSet
from .values import array_value

MATERIAL_WIDTH = 24
#: Columns of a material row past the first twelve (see the module docstring).
COL_BINDINGS = 12          # 12..16: texture binding of diffuse, emissive, roughness, metallic, opacity (-1: none)
COL_METALLIC_WORKFLOW = 17
COL_DIELECTRIC_F0 = 18
COL_METALLIC = 19
COL_OPACITY_THRESHOLD = 20
COL_TEXTURED = 21          # 1: the kernel evaluates bindings and the metallic mix per hit
COL_NORMAL_BINDING = 22    # texture binding of `normal` (tangent-space normal map), -1 none
COL_SHARED_RM_SAMPLE = 23  # 1: roughness and metallic read one texture the same way (one sample)
_BOUND_INPUTS = ("diffuseColor", "emissiveColor", "roughness", "metallic", "opacity", "normal")
#: USD's own UsdPreviewSurface fallbacks.
FALLBACKS = {
    "diffuseColor": (0.18, 0.18, 0.18), "emissiveColor": (0.0, 0.0, 0.0),
    "specularColor": (0.0, 0.0, 0.0), "useSpecularWorkflow": 0, "roughness": 0.5,
    "metallic": 0.0, "ior": 1.5, "opacity": 1.0, "opacityThreshold": 0.0, "normal": (0.0, 0.0, 1.0),
}
_READ = set(FALLBACKS) | {"clearcoat", "clearcoatRoughness", "displacement", "occlusion"}
_TEXTURE_FALLBACK = (0.0, 0.0, 0.0, 1.0)   # UsdUVTexture's own fallback


def display_color_row() -> np.ndarray:
    """Material for prims without a bound UsdPreviewSurface: displayColor as Lambert diffuse."""
    row = np.zeros(MATERIAL_WIDTH, np.float32)
    row[9] = 0.5  # roughness (unused: F0 is 0)
    row[10] = 1.0  # use displayColor
    row[11] = 1.0
    row[COL_BINDINGS:COL_BINDINGS + 5] = -1
    row[COL_NORMAL_BINDING] = -1
    return row


def _producer(inp: UsdShade.Input):
    """The attribute that gives an input its value, through node graphs and interface inputs:
    (attribute, is a shader output) or (None, False) when nothing does."""
    attrs = inp.GetValueProducingAttributes()
    if not attrs:
        return None, False
    return attrs[0], UsdShade.Output.IsOutput(attrs[0])


def _shader_input(shader: UsdShade.Shader, name: str, frame: float, default):
    """A node input's value (through connections to interface inputs), else `default`."""
    inp = shader.GetInput(name)
    if not inp:
        return default
    attr, is_output = _producer(inp)
    if attr is None or is_output:
        return default
    value = attr.Get(Usd.TimeCode(frame))
    return default if value is None else value


class _Source:
    """Where a UsdPreviewSurface input comes from: a constant, a texture binding, or a primvar."""

    def __init__(self, value=None, binding: int = -1, primvar: str | None = None, st: str | None = None):
        self.value, self.binding, self.primvar, self.st = value, binding, primvar, st


def _input_source(shader: UsdShade.Shader, name: str, frame: float, material_path: str,
                  textures: TextureSet) -> _Source:
    inp = shader.GetInput(name)
    if not inp:
        return _Source(FALLBACKS[name])
    attr, is_output = _producer(inp)
    if attr is None:
        return _Source(FALLBACKS[name])
    if not is_output:
        value = attr.Get(Usd.TimeCode(frame))
        return _Source(FALLBACKS[name] if value is None else _finite(value, name, material_path))
    node = UsdShade.Shader(attr.GetPrim())
    node_id = node.GetIdAttr().Get() if node else None
    output = UsdShade.Output(attr).GetBaseName()
    if node_id == "UsdUVTexture" and name in _BOUND_INPUTS:
        return _texture_source(node, output, name, frame, material_path, textures)
    readers = {"diffuseColor": ("UsdPrimvarReader_float3", "UsdPrimvarReader_float4"),
               "opacity": ("UsdPrimvarReader_float",)}
    if node_id in readers.get(name, ()):
        varname = str(_shader_input(node, "varname", frame, "") or "")
        if varname:
            return _Source(_finite(_shader_input(node, "fallback", frame, FALLBACKS[name]), name, material_path)
                           if name == "opacity" else FALLBACKS[name], primvar=varname)
    fallback = _finite(_shader_input(node, "fallback", frame, FALLBACKS[name]), name, material_path) \
        if node_id and node_id.startswith("UsdPrimvarReader") else FALLBACKS[name]
    warn_once(f"connected:{material_path}:{name}",
              f"material {material_path}: input '{name}' comes from a {node_id or 'node'} that warp_blur does not "
              f"evaluate; using {fallback}")
    return _Source(fallback)


def _texture_source(node: UsdShade.Shader, output: str, name: str, frame: float, material_path: str,
                    textures: TextureSet) -> _Source:
    """A UsdUVTexture feeding `name` through output rgb/r/g/b/a: a binding, or its fallback."""
    get = lambda n, d: _shader_input(node, n, frame, d)  # noqa: E731
    fallback = np.asarray(get("fallback", _TEXTURE_FALLBACK), np.float64).reshape(-1)
    fallback = np.resize(fallback, 4) if fallback.size else np.asarray(_TEXTURE_FALLBACK)
    channel_value = {"rgb": fallback[:3], "r": fallback[0], "g": fallback[1], "b": fallback[2], "a": fallback[3]}
    const = channel_value.get(output, fallback[:3])
    if np.ndim(const) == 0 and np.ndim(FALLBACKS[name]) == 1:
        const = (float(const),) * 3
    elif np.ndim(const) == 1 and np.ndim(FALLBACKS[name]) == 0:
        const = float(const[0])
    asset = get("file", None)
    resolved = getattr(asset, "resolvedPath", "") if asset is not None else ""
    if "<UDIM>" in getattr(asset, "path", ""):
        return _udim_source(node, asset.path, output, name, frame, material_path, textures, const, fallback)
    if not resolved:
        warn_once(f"texfile:{material_path}:{name}",
                  f"material {material_path}: the texture for '{name}' has no file that resolves "
                  f"({getattr(asset, 'path', asset)}); using its fallback")
        return _Source(_finite(const, name, material_path))
    space = str(get("sourceColorSpace", "auto"))
    added = textures.add_texture(resolved, space, str(get("wrapS", "useMetadata")), str(get("wrapT", "useMetadata")))
    if added is None:
        return _Source(_finite(const, name, material_path))
    scale, bias = _scale_bias(node, name, frame, material_path)
    st_name, st_transform = _st_source(node, frame, material_path)
    binding = textures.add_binding(added[0], output, scale, bias, st_transform=st_transform)
    return _Source(_finite(const, name, material_path), binding=binding, st=st_name)


def _st_source(node: UsdShade.Shader, frame: float, material_path: str) -> tuple[str, tuple]:
    """(the primvar a UsdUVTexture's `st` reads through a UsdPrimvarReader_float2, else "st";
    the UsdTransform2d between them as (m00, m01, m10, m11, tx, ty), identity when none). USD's
    Transform2d scales, then rotates counter-clockwise by `rotation` degrees, then translates."""
    transform = IDENTITY_ST
    inp = node.GetInput("st")
    for _hop in range(4):          # a reader, possibly behind one (or a few) Transform2d nodes
        if not inp:
            return "st", transform
        attr, is_output = _producer(inp)
        if attr is None or not is_output:
            return "st", transform
        src = UsdShade.Shader(attr.GetPrim())
        if src.GetIdAttr().Get() != "UsdTransform2d":
            return str(_shader_input(src, "varname", frame, "st") or "st"), transform
        scale = np.asarray(_shader_input(src, "scale", frame, (1.0, 1.0)), np.float64).reshape(-1)
        angle = np.radians(float(_shader_input(src, "rotation", frame, 0.0)))
        shift = np.asarray(_shader_input(src, "translation", frame, (0.0, 0.0)), np.float64).reshape(-1)
        if scale.size != 2 or shift.size != 2 or not (np.isfinite(scale).all() and np.isfinite(shift).all()
                                                      and np.isfinite(angle)):
            warn_once(f"st2d:{material_path}", f"material {material_path}: a UsdTransform2d has non-finite "
                                               f"inputs; ignored")
        else:
            c, s = np.cos(angle), np.sin(angle)
            m = np.array([[c * scale[0], -s * scale[1]], [s * scale[0], c * scale[1]]])
            # walking from the texture towards the reader: this node applies before those found so far
            outer = np.array([[transform[0], transform[1]], [transform[2], transform[3]]])
            t = outer @ shift + np.array(transform[4:6])
            mm = outer @ m
            transform = (mm[0, 0], mm[0, 1], mm[1, 0], mm[1, 1], t[0], t[1])
        inp = src.GetInput("in")
    return "st", transform


def _scale_bias(node: UsdShade.Shader, name: str, frame: float, material_path: str):
    get = lambda n, d: _shader_input(node, n, frame, d)  # noqa: E731
    scale = np.resize(np.asarray(get("scale", (1.0, 1.0, 1.0, 1.0)), np.float64).reshape(-1), 4)
    bias = np.resize(np.asarray(get("bias", (0.0, 0.0, 0.0, 0.0)), np.float64).reshape(-1), 4)
    if not (np.isfinite(scale).all() and np.isfinite(bias).all()):
        warn_once(f"texscale:{material_path}:{name}", f"material {material_path}: texture scale/bias for '{name}' "
                                                      f"is not finite; using 1 and 0")
        scale, bias = np.ones(4), np.zeros(4)
    return scale, bias


def _udim_source(node: UsdShade.Shader, pattern: str, output: str, name: str, frame: float, material_path: str,
                 textures: TextureSet, const, fallback: np.ndarray) -> _Source:
    """A UsdUVTexture whose file is a UDIM set (`<UDIM>` in its path): its tiles found as USD
    finds them (UsdShade.UdimUtils, relative to the layer that authors the path), or its fallback."""
    attr = _producer(node.GetInput("file"))[0]
    stack = attr.GetPropertyStack(Usd.TimeCode(frame)) if attr is not None else []
    layer = stack[0].layer if stack else node.GetPrim().GetStage().GetRootLayer()

    def find() -> list[tuple[str, int]]:
        return [(path, int(tile)) for path, tile in UsdShade.UdimUtils.ResolveUdimTilePaths(pattern, layer)
                if str(tile).isdigit()]
    tiles = find()
    textures.note_udim_set(find, tiles)   # a kept table is read again when the tiles found change
    space = str(_shader_input(node, "sourceColorSpace", frame, "auto"))
    base = textures.add_udim(tiles, space, fallback) if tiles else None
    if base is None:
        warn_once(f"udim:{material_path}:{name}", f"material {material_path}: no tile of the UDIM texture "
                                                  f"{pattern} for '{name}' can be read; using its fallback")
        return _Source(_finite(const, name, material_path))
    scale, bias = _scale_bias(node, name, frame, material_path)
    st_name, st_transform = _st_source(node, frame, material_path)
    binding = textures.add_binding(base, output, scale, bias, udim=True, st_transform=st_transform)
    return _Source(_finite(const, name, material_path), binding=binding, st=st_name)


def _items(value) -> list:
    """The elements of a vector value: a Gf vector's own buffer where it has one of floats
    (iterating one costs ~12 us: its iteration ends on an exception), else by index."""
    try:
        view = memoryview(value)
    except TypeError:
        return [value[i] for i in range(len(value))]
    if view.ndim != 1 or view.format not in ("f", "d", "e"):
        raise TypeError("not a vector of floats")
    return view.tolist()


def _plainly_finite(value, fallback) -> bool:
    """True when value is a number (fallback a number) or a sequence of as many numbers as the
    fallback tuple, all finite and at most 1e30 in size: _finite's test without NumPy, which costs
    more than the test for one scalar (a material reads ten inputs a frame). False may still pass
    _finite's own test."""
    try:
        nums = [float(x) for x in _items(value)] if isinstance(fallback, tuple) else [float(value)]
    except (TypeError, ValueError):
        return False
    if isinstance(fallback, tuple) and len(nums) != len(fallback):
        return False
    return all(math.isfinite(x) and abs(x) <= 1e30 for x in nums)


def _finite(value, name: str, material_path: str):
    """value when it is a finite number (or vector) of USD's type for the input, else USD's
    fallback with a warning (once per material and input): a NaN must never reach a pixel."""
    if _plainly_finite(value, FALLBACKS[name]):
        return value
    try:
        arr = np.asarray(value, np.float64).reshape(np.shape(FALLBACKS[name]))
        ok = bool(np.isfinite(arr).all()) and np.abs(arr).max(initial=0.0) <= 1e30
    except (TypeError, ValueError):
        ok = False
    if ok:
        return value
    warn_once(f"nonfinite:{material_path}:{name}",
              f"material {material_path}: input '{name}' = {value} is not a finite value; "
              f"using USD's fallback {FALLBACKS[name]}")
    return FALLBACKS[name]


@dataclass
class MaterialReads:
    """What a material needs from the prims it is bound to: the primvar of its texture
    coordinates (None: untextured), of its diffuse colour and of its opacity (None: not from a
    primvar)."""

    st: str | None = None
    color: str | None = None
    opacity: str | None = None


def preview_surface_row(material: UsdShade.Material, frame: float,
                        textures: TextureSet) -> tuple[np.ndarray, MaterialReads] | None:
    """The table row for a bound material and the primvars it reads, or None when it has no
    UsdPreviewSurface."""
    path = str(material.GetPath())
    surface = material.ComputeSurfaceSource()
    shader = surface[0] if surface else None
    if not shader or shader.GetIdAttr().Get() != "UsdPreviewSurface":
        warn_once(f"material:{path}", f"material {path} has no UsdPreviewSurface: using displayColor")
        return None
    for inp in shader.GetInputs():
        if inp.GetBaseName() not in _READ:
            warn_once(f"input:{path}:{inp.GetBaseName()}",
                      f"material {path}: input '{inp.GetBaseName()}' is not read by warp_blur")
    src = {n: _input_source(shader, n, frame, path, textures) for n in _BOUND_INPUTS}
    get = lambda n: _input_source(shader, n, frame, path, textures).value  # noqa: E731
    diffuse = np.asarray(src["diffuseColor"].value, np.float64)
    emissive = np.asarray(src["emissiveColor"].value, np.float64)
    roughness = float(src["roughness"].value)
    opacity = float(src["opacity"].value)
    threshold = float(get("opacityThreshold"))
    textured = any(s.binding >= 0 for s in src.values()) or src["diffuseColor"].primvar is not None
    specular_workflow = bool(int(get("useSpecularWorkflow")))
    metallic = float(np.clip(src["metallic"].value, 0.0, 1.0))
    ior = float(get("ior"))
    dielectric = ((ior - 1.0) / (ior + 1.0)) ** 2
    if specular_workflow:
        f0 = np.asarray(get("specularColor"), np.float64)
    else:
        f0 = (1.0 - metallic) * dielectric + metallic * diffuse
        if not textured:   # a textured material mixes per hit, from its raw diffuse
            diffuse = diffuse * (1.0 - metallic)
    row = np.zeros(MATERIAL_WIDTH, np.float32)
    row[0:3], row[3:6], row[6:9] = diffuse, emissive, f0
    row[9] = np.clip(roughness, 0.02, 1.0)
    row[10] = 1.0 if src["diffuseColor"].primvar is not None else 0.0
    row[11] = opacity
    row[COL_BINDINGS:COL_BINDINGS + 5] = [src[n].binding for n in _BOUND_INPUTS[:5]]
    row[COL_NORMAL_BINDING] = src["normal"].binding
    row[COL_METALLIC_WORKFLOW] = 0.0 if specular_workflow else 1.0
    row[COL_DIELECTRIC_F0] = dielectric
    row[COL_METALLIC] = metallic
    row[COL_OPACITY_THRESHOLD] = threshold
    row[COL_TEXTURED] = 1.0 if textured else 0.0
    row[COL_SHARED_RM_SAMPLE] = 1.0 if textures.same_sample(src["roughness"].binding,
                                                            src["metallic"].binding) else 0.0
    st = next((s.st for s in src.values() if s.binding >= 0 and s.st), None)
    return row, MaterialReads(st=st, color=src["diffuseColor"].primvar, opacity=src["opacity"].primvar)


#: kernels/cutout.py's code for a triangle whose opacity is its corners' opacity primvar
#: (displayOpacity), interpolated at the hit (Geometry.tri_alpha)
CODE_CORNER_OPACITY = -4.0


class MaterialTable:
    """Deduplicated material rows; index 0 is the displayColor material."""

    def __init__(self, frame: float) -> None:
        self.frame = frame
        self.rows: list[np.ndarray] = [display_color_row()]
        self.names: list[str] = ["<displayColor>"]
        self.reads: list[MaterialReads] = [MaterialReads(color="displayColor", opacity="displayOpacity")]
        self.textures = TextureSet()
        self._index: dict[str, int] = {}

    def index_for_prim(self, prim: Usd.Prim) -> int:
        """Material index of the prim's bound material (0 = displayColor)."""
        material, _ = UsdShade.MaterialBindingAPI(prim).ComputeBoundMaterial()
        if not material:
            return 0
        key = str(material.GetPath())
        if key not in self._index:
            made = preview_surface_row(material, self.frame, self.textures)
            if made is None:
                self._index[key] = 0
            else:
                self._index[key] = len(self.rows)
                self.rows.append(made[0])
                self.reads.append(made[1])
                self.names.append(key)
        return self._index[key]

    def subset_materials(self, prim: Usd.Prim, t: Usd.TimeCode, material: int,
                          face_of_tri: np.ndarray) -> np.ndarray | None:
        """(T,) material of each triangle from the mesh's GeomSubsets of family materialBind (the
        mesh's own material elsewhere), or None when no subset binds another material."""
        subsets = UsdShade.MaterialBindingAPI(prim).GetMaterialBindSubsets()
        if not subsets:
            return None
        out = np.full(len(face_of_tri), material, np.int32)
        for subset in subsets:
            faces = array_value(subset.GetIndicesAttr(), t, np.int64)
            if len(faces):
                out[np.isin(face_of_tri, faces)] = self.index_for_prim(subset.GetPrim())
        return out if (out != material).any() else None

    def array(self) -> np.ndarray:
        return np.stack(self.rows).astype(np.float32)

    def cutouts(self) -> np.ndarray:
        """(M, 3) float32 per material: its opacity test (kernels/cutout.py): (code, threshold,
        constant opacity) with code -1 none (opaque), -2 hidden everywhere, -3 a constant
        opacity, else the binding of a textured opacity. USD masks where opacityThreshold > 0
        (points below it are not there, the rest opaque); with threshold 0, opacity < 1 (or
        textured) is fractional."""
        a = self.array()
        threshold, binding, opacity = a[:, COL_OPACITY_THRESHOLD], a[:, COL_BINDINGS + 4], a[:, 11]
        mask = threshold > 0
        fractional = self.fractional()
        code = np.full(len(a), -1.0)
        code = np.where(mask & (binding >= 0), binding, code)
        code = np.where(mask & (binding < 0) & (opacity < threshold), -2.0, code)
        code = np.where(fractional, np.where(binding >= 0, binding, -3.0), code)
        return np.stack([code, threshold, np.clip(opacity, 0.0, 1.0)], axis=1).astype(np.float32)

    def fractional(self) -> np.ndarray:
        """(M,) bool: the material's opacity is fractional (threshold 0, opacity < 1 or textured)."""
        a = self.array()
        return (a[:, COL_OPACITY_THRESHOLD] <= 0) & ((a[:, COL_BINDINGS + 4] >= 0) | (a[:, 11] < 1.0))

    def emissive_only(self) -> np.ndarray:
        """(M,) bool: radiance cannot depend on lights (black diffuse and specular)."""
        a = self.array()
        return ((np.abs(a[:, 0:3]).max(axis=1) == 0) & (np.abs(a[:, 6:9]).max(axis=1) == 0) & (a[:, 10] == 0)
                & (a[:, COL_TEXTURED] == 0))

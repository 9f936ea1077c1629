"""UsdPreviewSurface (through material binding) and displayColor into a flat material table.

Each row of the table (float32, MATERIAL_WIDTH columns) is read by `shading.py`:
diffuse rgb, emissive rgb, F0 rgb (specular reflectance at normal incidence), roughness,
use_display_color (1 = diffuse comes from the triangle's displayColor), opacity.
The specular F0 follows UsdPreviewSurface: specularColor in the specular workflow, else
lerp(((ior-1)/(ior+1))^2, diffuseColor, metallic) with the diffuse scaled by (1 - metallic).
Textures and other connected inputs are not read: the input's fallback is used, with a warning.
"""

from __future__ import annotations

import numpy as np
from pxr import Usd, UsdShade

from .log import warn_once

MATERIAL_WIDTH = 12
#: USD's own UsdPreviewSurface fallbacks.
FALLBACKS = {
    "diffuseColor": (0.18, 0.18, 0.18), "emissiveColor": (0.0, 0.0, 0.0),
    "specularColor": (0.0, 0.0, 0.0), "useSpecularWorkflow": 0, "roughness": 0.5,
    "metallic": 0.0, "ior": 1.5, "opacity": 1.0,
}
_READ = set(FALLBACKS) | {"clearcoat", "clearcoatRoughness", "opacityThreshold", "displacement",
                          "occlusion", "normal"}


def display_color_row() -> np.ndarray:
    """Material for prims without a bound UsdPreviewSurface: displayColor as Lambert diffuse."""
    row = np.zeros(MATERIAL_WIDTH, np.float32)
    row[9] = 0.5  # roughness (unused: F0 is 0)
    row[10] = 1.0  # use displayColor
    row[11] = 1.0
    return row


def _input_value(shader: UsdShade.Shader, name: str, frame: float, material_path: str):
    inp = shader.GetInput(name)
    if not inp:
        return FALLBACKS[name]
    if inp.HasConnectedSource():
        attrs = inp.GetValueProducingAttributes()
        if attrs and attrs[0].GetPrim() != shader.GetPrim() and UsdShade.Input.IsInput(attrs[0]):
            value = attrs[0].Get(Usd.TimeCode(frame))
            if value is not None:
                return _finite(value, name, material_path)
        warn_once(f"connected:{material_path}:{name}",
                  f"material {material_path}: input '{name}' is connected (texture or node graph), "
                  f"which warp_blur does not evaluate; using USD's fallback {FALLBACKS[name]}")
        return FALLBACKS[name]
    value = inp.Get(Usd.TimeCode(frame))
    return FALLBACKS[name] if value is None else _finite(value, name, material_path)


def _finite(value, name: str, material_path: str):
    """value when it is a finite number (or vector) of USD's type for the input, else USD's
    fallback with a warning (once per material and input): a NaN must never reach a pixel."""
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


def preview_surface_row(material: UsdShade.Material, frame: float) -> np.ndarray | None:
    """The table row for a bound material, or None when it has no UsdPreviewSurface."""
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
    get = lambda n: _input_value(shader, n, frame, path)  # noqa: E731
    diffuse = np.asarray(get("diffuseColor"), np.float64)
    emissive = np.asarray(get("emissiveColor"), np.float64)
    roughness = float(get("roughness"))
    opacity = float(get("opacity"))
    if opacity < 1.0:
        warn_once(f"opacity:{path}", f"material {path}: opacity {opacity} < 1 is not supported (rendered opaque)")
    if int(get("useSpecularWorkflow")):
        f0 = np.asarray(get("specularColor"), np.float64)
    else:
        metallic = float(np.clip(get("metallic"), 0.0, 1.0))
        ior = float(get("ior"))
        dielectric = ((ior - 1.0) / (ior + 1.0)) ** 2
        f0 = (1.0 - metallic) * dielectric + metallic * diffuse
        diffuse = diffuse * (1.0 - metallic)
    row = np.zeros(MATERIAL_WIDTH, np.float32)
    row[0:3], row[3:6], row[6:9] = diffuse, emissive, f0
    row[9] = np.clip(roughness, 0.02, 1.0)
    row[10] = 0.0
    row[11] = opacity
    return row


class MaterialTable:
    """Deduplicated material rows; index 0 is the displayColor material."""

    def __init__(self, frame: float) -> None:
        self.frame = frame
        self.rows: list[np.ndarray] = [display_color_row()]
        self.names: list[str] = ["<displayColor>"]
        self._index: dict[str, int] = {}

    def index_for_prim(self, prim: Usd.Prim) -> int:
        """Material index of the prim's bound material (0 = displayColor)."""
        material, _ = UsdShade.MaterialBindingAPI(prim).ComputeBoundMaterial()
        if not material:
            return 0
        key = str(material.GetPath())
        if key not in self._index:
            row = preview_surface_row(material, self.frame)
            if row is None:
                self._index[key] = 0
            else:
                self._index[key] = len(self.rows)
                self.rows.append(row)
                self.names.append(key)
        return self._index[key]

    def array(self) -> np.ndarray:
        return np.stack(self.rows).astype(np.float32)

    def emissive_only(self) -> np.ndarray:
        """(M,) bool: radiance cannot depend on lights (black diffuse and specular)."""
        a = self.array()
        return (np.abs(a[:, 0:3]).max(axis=1) == 0) & (np.abs(a[:, 6:9]).max(axis=1) == 0) & (a[:, 10] == 0)

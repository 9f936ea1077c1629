"""A textured DomeLight: its latitude-longitude map as a texture binding (background along each
ray) and its irradiance as 9 spherical-harmonic coefficients (diffuse ambient per normal).

Orientation follows UsdLux: a DomeLight's top pole is its local +Y (DomeLight_1: `poleAxis`,
"scene" = the stage's up axis); within it the map follows OpenEXR's latlong layout (longitude
+pi at the image's left edge, -pi at its right, longitude 0 along +Z, pi/2 along +X, latitude
+pi/2 at the top row). Only `latlong` (and `automatic`) maps are read.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from pxr import Usd, UsdGeom, UsdLux

from ..core.log import warn_once
from .textures import TextureSet, read_image

#: SH irradiance convolution (Ramamoorthi & Hanrahan 2001): A_l for bands 0, 1, 2.
_BAND_GAIN = np.array([np.pi] + [2.0 * np.pi / 3.0] * 3 + [np.pi / 4.0] * 5)
#: Largest map side used for the irradiance integral (coarser mips give the same low bands).
_SH_SIDE = 64


@dataclass
class DomeMap:
    """The frame's textured dome: binding (TextureSet, scaled by the dome's radiance), rotation
    (3, 3) of world directions into dome directions (d_dome = d_world @ rotation), irradiance
    (9, 3) SH coefficients of E(n) in dome space, and the map's mean radiance (3,)."""

    binding: int
    rotation: np.ndarray
    irradiance: np.ndarray
    mean: np.ndarray


def sh_basis(d: np.ndarray) -> np.ndarray:
    """(N, 9) real SH basis at unit directions d (N, 3), in the order the kernel evaluates it."""
    x, y, z = d[:, 0], d[:, 1], d[:, 2]
    return np.stack([np.full_like(x, 0.282095), 0.488603 * y, 0.488603 * z, 0.488603 * x,
                     1.092548 * x * y, 1.092548 * y * z, 0.315392 * (3.0 * z * z - 1.0),
                     1.092548 * x * z, 0.546274 * (x * x - y * y)], axis=1)


def latlong_directions(w: int, h: int) -> tuple[np.ndarray, np.ndarray]:
    """Unit dome directions (h, w, 3) of the texel centres of a w×h latlong map and their solid
    angles (h, w) (sr; they sum to 4 pi)."""
    lon = np.pi - (np.arange(w) + 0.5) / w * 2.0 * np.pi
    lat = np.pi / 2.0 - (np.arange(h) + 0.5) / h * np.pi
    lon, lat = np.meshgrid(lon, lat)
    d = np.stack([np.cos(lat) * np.sin(lon), np.sin(lat), np.cos(lat) * np.cos(lon)], axis=-1)
    omega = np.cos(lat) * (2.0 * np.pi / w) * (np.pi / h)
    return d, omega


def irradiance_sh(radiance: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """(9, 3) SH coefficients of the irradiance E(n) of a latlong radiance map (h, w, 3), and the
    map's solid-angle mean radiance (3,)."""
    h, w = radiance.shape[:2]
    d, omega = latlong_directions(w, h)
    basis = sh_basis(d.reshape(-1, 3)) * omega.reshape(-1, 1)                 # (N, 9)
    coeffs = basis.T @ radiance.reshape(-1, 3).astype(np.float64)             # (9, 3)
    mean = (radiance.reshape(-1, 3) * omega.reshape(-1, 1)).sum(axis=0) / omega.sum()
    return coeffs * _BAND_GAIN[:, None], mean


def _pole_rotation(prim: Usd.Prim) -> np.ndarray:
    """(3, 3) rotation taking dome-local directions (pole +Y) to the prim's frame (row vectors)."""
    pole = "Y"
    if prim.IsA(UsdLux.DomeLight_1):
        pole = str(UsdLux.DomeLight_1(prim).GetPoleAxisAttr().Get() or "scene")
        if pole == "scene":
            pole = str(UsdGeom.GetStageUpAxis(prim.GetStage()))
    if pole == "Z":   # +Y -> +Z, +Z -> -Y
        return np.array([[1.0, 0.0, 0.0], [0.0, 0.0, 1.0], [0.0, -1.0, 0.0]])
    return np.eye(3)


def dome_map(prim: Usd.Prim | None, frame: float, radiance: np.ndarray, textures: TextureSet) -> DomeMap | None:
    """The textured dome of `prim` (None when it has no readable latlong texture: the dome is then
    its uniform radiance), its map added to `textures`."""
    if prim is None or not radiance.any():
        return None
    path = str(prim.GetPath())
    dl = UsdLux.DomeLight(prim) if prim.IsA(UsdLux.DomeLight) else UsdLux.DomeLight_1(prim)
    asset = dl.GetTextureFileAttr().Get(Usd.TimeCode(frame))
    resolved = getattr(asset, "resolvedPath", "") if asset is not None else ""
    if not asset or not getattr(asset, "path", ""):
        return None
    fmt = str(dl.GetTextureFormatAttr().Get() or "automatic")
    if fmt not in ("latlong", "automatic"):
        warn_once(f"domefmt:{path}", f"dome light {path}: texture format '{fmt}' is not supported "
                                     "(uniform colour used)")
        return None
    found = textures.add_texture(resolved, "auto", "repeat", "clamp") if resolved else None
    if found is None:
        warn_once(f"domefile:{path}", f"dome light {path}: its texture {asset.path} cannot be read "
                                      "(uniform colour used)")
        return None
    texture, _side = found
    levels = read_image(resolved, "auto")
    level = next((lev for lev in levels if max(lev.shape[:2]) <= _SH_SIDE), levels[-1])
    coeffs, mean = irradiance_sh(level[..., :3].astype(np.float64) * radiance[None, None, :])
    binding = textures.add_binding(texture, "rgb", (*radiance, 1.0), (0.0, 0.0, 0.0, 0.0))
    world = np.array(UsdGeom.Xformable(prim).ComputeLocalToWorldTransform(Usd.TimeCode(frame)), np.float64)[:3, :3]
    world = _pole_rotation(prim) @ world
    world = world / np.maximum(np.linalg.norm(world, axis=1, keepdims=True), 1e-30)
    # d_world = d_dome @ world, so d_dome = d_world @ world^-1 (= world^T for a rotation)
    try:
        rotation = np.linalg.inv(world)
    except np.linalg.LinAlgError:   # a zero scale leaves no orientation
        warn_once(f"domexf:{path}", f"dome light {path}: its transform has no orientation (a zero scale); "
                                    "its map is read unrotated")
        rotation = np.eye(3)
    return DomeMap(binding, rotation, coeffs.astype(np.float32), mean.astype(np.float32))


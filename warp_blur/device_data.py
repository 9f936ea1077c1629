"""Host NumPy -> Warp structs (float64 camera-space positions become float32 here, and only here)."""

from __future__ import annotations

import numpy as np
import warp as wp

from .binning import TileBins
from .camera import Projection
from .kernel_types import Bins, Geometry, Shading, View
from .shadow_lookup import FACE_WIDTH


def device_array(a: np.ndarray, dtype, device: str, min_len: int = 1):
    """A Warp array of `a` (padded with zeros to min_len rows: kernels take no empty arrays)."""
    a = np.ascontiguousarray(a)
    if len(a) < min_len:
        shape = (min_len,) + a.shape[1:]
        a = np.zeros(shape, a.dtype)
    return wp.array(a, dtype=dtype, device=device)


def make_view(proj: Projection, spatial: int, bins: TileBins | None, tile_size: int) -> View:
    v = View()
    v.width, v.height = proj.width, proj.height
    x0, y0, x1, y1 = proj.window
    v.win_min = wp.vec2(x0, y0)
    v.win_max = wp.vec2(x1, y1)
    v.ortho = 1 if proj.orthographic else 0
    v.near, v.far = proj.near, proj.far
    v.spatial = spatial
    v.tile_size = tile_size
    v.tiles_x = bins.tiles_x if bins is not None else (proj.width + tile_size - 1) // tile_size
    return v


class TriangleTables:
    """Per-triangle data uploaded once per frame (topology, flags, materials, colours)."""

    def __init__(self, tri_vertices: np.ndarray, tri_flags: np.ndarray, tri_material: np.ndarray,
                 tri_colors: np.ndarray, device: str) -> None:
        self.tri_vertices = device_array(tri_vertices.astype(np.int32), wp.vec3i, device)
        self.tri_flags = device_array(tri_flags.astype(np.int32), int, device)
        self.tri_material = device_array(tri_material.astype(np.int32), int, device)
        self.tri_colors = device_array(tri_colors.astype(np.float32), wp.vec3, device)
        self.device = device


def make_geometry(tables: TriangleTables, positions: np.ndarray, normals: np.ndarray | None,
                  entry_tri: np.ndarray, entry_k0: np.ndarray, entry_k1: np.ndarray,
                  velocities: np.ndarray | None = None) -> Geometry:
    """positions: (K+1, V, 3) camera space (float64 ok); normals: same shape or None;
    velocities: (V, 3) camera-space units per shutter of the vertices at a sharp instant, for
    shadow lookups in maps of other instants (None: static entries hold still)."""
    dev = tables.device
    g = Geometry()
    k1, v = positions.shape[0], max(positions.shape[1], 1)
    pos = np.zeros((k1, v, 3), np.float32)
    pos[:, :positions.shape[1]] = positions
    g.positions = wp.array(pos, dtype=wp.vec3, device=dev)
    if normals is None or normals.size == 0:
        g.normals = wp.zeros((1, 1), dtype=wp.vec3, device=dev)
    else:
        g.normals = wp.array(np.ascontiguousarray(normals, np.float32), dtype=wp.vec3, device=dev)
    g.tri_vertices, g.tri_flags = tables.tri_vertices, tables.tri_flags
    g.tri_material, g.tri_colors = tables.tri_material, tables.tri_colors
    g.entry_tri = device_array(entry_tri.astype(np.int32), int, dev)
    g.entry_k0 = device_array(entry_k0.astype(np.int32), int, dev)
    g.entry_k1 = device_array(entry_k1.astype(np.int32), int, dev)
    g.num_segments = max(k1 - 1, 1)
    if velocities is None or velocities.size == 0:
        g.velocities = wp.zeros(1, dtype=wp.vec3, device=dev)
        g.has_velocities = 0
    else:
        g.velocities = wp.array(np.ascontiguousarray(velocities, np.float32), dtype=wp.vec3, device=dev)
        g.has_velocities = 1
    return g


def make_shading(materials: np.ndarray, lights: np.ndarray, dome: np.ndarray, device: str,
                 shadows=None, options=None) -> Shading:
    """lights: (L+1, NL, LIGHT_WIDTH) tables at L+1 knots over the shutter; shadows: a
    shadow_maps.ShadowData (or None: no light casts shadows) with its ShadowOptions."""
    s = Shading()
    s.materials = wp.array(np.ascontiguousarray(materials, np.float32), dtype=float, device=device)
    nl = lights.shape[1]
    lt = lights if nl else np.zeros((lights.shape[0], 1, lights.shape[2]), np.float32)
    s.lights = wp.array(np.ascontiguousarray(lt, np.float32), dtype=float, device=device)
    s.num_lights = nl
    s.light_segments = lights.shape[0] - 1
    s.dome = wp.vec3(*[float(x) for x in dome])
    # per light: first map (-1 = no shadow), light samples, faces, 1 when the light holds still
    # over the shutter (its maps' texel flags then tell where a time span needs one lookup)
    if shadows is None:
        s.shadow_maps = wp.zeros((1, 1, 1), dtype=float, device=device)
        s.shadow_varying = wp.zeros((1, 1, 1), dtype=wp.uint8, device=device)
        s.shadow_faces = wp.zeros((1, FACE_WIDTH), dtype=float, device=device)
        info = np.full((max(nl, 1), 4), -1, np.int32)
        s.shadow_lights = wp.array(info, dtype=int, device=device)
        s.shadow_times, s.shadow_size = 1, 1
    else:
        s.shadow_maps = wp.array(shadows.maps, dtype=float, device=device)
        varying = shadows.varying if shadows.varying is not None else np.ones((1, 1, 1), np.uint8)
        s.shadow_varying = wp.array(varying, dtype=wp.uint8, device=device)
        s.shadow_faces = wp.array(shadows.faces, dtype=float, device=device)
        info = np.zeros((len(shadows.lights), 4), np.int32)
        info[:, :3] = shadows.lights
        if shadows.varying is not None:
            info[:nl, 3] = (lt == lt[:1]).all(axis=(0, 2))[:nl]
        s.shadow_lights = wp.array(info, dtype=int, device=device)
        s.shadow_times, s.shadow_size = shadows.times, shadows.size
    s.shadow_bias = float(options.bias) if options is not None else 1.0
    s.shadow_normal_bias = float(options.normal_bias) if options is not None else 1.5
    s.shadow_pcf = int(options.pcf) if options is not None else 0
    return s


def make_bins(bins: TileBins, device: str) -> Bins:
    b = Bins()
    b.tile_offsets = device_array(bins.tile_offsets, int, device)
    b.tile_entries = device_array(bins.tile_entries, int, device)
    boxes = bins.entry_boxes if bins.entry_boxes is not None else np.zeros((0, 4), np.float32)
    b.entry_boxes = device_array(boxes.astype(np.float32), wp.vec4, device)
    return b

"""Host NumPy -> Warp structs (float64 camera-space positions become float32 here, and only here)."""

from __future__ import annotations

import threading
from collections import OrderedDict

import numpy as np
import warp as wp

from .binning import TileBins, pass_all_slabs
from ..core.camera import Projection
from ..core.reuse import reused_empty
from ..kernels.kernel_types import Bins, Geometry, Shading, Textures, View
from ..kernels.shadow_lookup import FACE_WIDTH


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
    """Per-triangle data uploaded once per frame (topology, flags, materials, corner colours
    (3T, 3), and for textured scenes corner texture coordinates (3T, 2), levels of detail (T,),
    and opacity tests (T, 3) with the textures and corner opacities (T, 3) they read (cutout.py))."""

    def __init__(self, tri_vertices: np.ndarray, tri_flags: np.ndarray, tri_material: np.ndarray,
                 corner_colors: np.ndarray, device: str, corner_uvs: np.ndarray | None = None,
                 tri_lod: np.ndarray | None = None, tri_cutout: np.ndarray | None = None,
                 textures=None, tri_alpha: np.ndarray | None = None) -> None:
        self.tri_vertices = device_array(tri_vertices.astype(np.int32), wp.vec3i, device)
        self.tri_flags = device_array(tri_flags.astype(np.int32), int, device)
        self.tri_material = device_array(tri_material.astype(np.int32), int, device)
        self.tri_colors = device_array(corner_colors.astype(np.float32), wp.vec3, device)
        empty = np.zeros(0, np.float32)
        self.tri_uvs = device_array((corner_uvs if corner_uvs is not None else empty.reshape(0, 2)).astype(np.float32),
                                    wp.vec2, device)
        self.tri_lod = device_array((tri_lod if tri_lod is not None else empty).astype(np.float32), float, device)
        self.has_cutouts = tri_cutout is not None and bool((tri_cutout[:, 0] != -1).any())
        cut = tri_cutout if self.has_cutouts else empty.reshape(0, 3)
        self.tri_cutout = device_array(cut.astype(np.float32), wp.vec3, device)
        self.textures = texture_arrays(textures if self.has_cutouts else None, device)
        alpha = tri_alpha if self.has_cutouts and tri_alpha is not None else empty.reshape(0, 3)
        self.tri_alpha = device_array(alpha.astype(np.float32), wp.vec3, device)
        self.device = device


def make_geometry(tables: TriangleTables, positions: np.ndarray, normals: np.ndarray | None,
                  entry_tri: np.ndarray, entry_k0: np.ndarray, entry_k1: np.ndarray,
                  velocities: np.ndarray | None = None) -> Geometry:
    """positions: (K+1, V, 3) camera space (float64 ok), or a (K+1, V) float32 wp.vec3 array on
    the device, taken as it is (shadows/vertex_passes.face_positions); normals: (K+1, V, 3) or None;
    velocities: (V, 3) camera-space units per shutter of the vertices at a sharp instant, for
    shadow lookups in maps of other instants (None: static entries hold still)."""
    dev = tables.device
    g = Geometry()
    k1 = positions.shape[0]
    if isinstance(positions, wp.array):
        g.positions = positions
    else:
        pos = np.zeros((k1, max(positions.shape[1], 1), 3), np.float32)
        pos[:, :positions.shape[1]] = positions
        g.positions = wp.array(pos, dtype=wp.vec3, device=dev)
    if normals is None or normals.size == 0:
        g.normals = wp.zeros((1, 1), dtype=wp.vec3, device=dev)
    else:
        g.normals = wp.array(np.ascontiguousarray(normals, np.float32), dtype=wp.vec3, device=dev)
    g.tri_vertices, g.tri_flags = tables.tri_vertices, tables.tri_flags
    g.tri_material, g.tri_colors = tables.tri_material, tables.tri_colors
    g.tri_uvs, g.tri_lod = tables.tri_uvs, tables.tri_lod
    g.tri_cutout, g.has_cutouts, g.tex = tables.tri_cutout, int(tables.has_cutouts), tables.textures
    g.tri_alpha = tables.tri_alpha
    g.cutout_slots = 256   # the analytic method sets its own (its time bits)
    g.presence_shift = 0
    g.clip_bits = 0   # the analytic method sets its time bits
    g.shadow_free = _no_flags(dev)   # set against a Shading's maps by shadows/free_entries.py
    g.entry_edges = wp.zeros((1, 1), dtype=wp.vec3, device=dev)   # filled by analytic/coverage.py's edge_table
    g.entry_corners = wp.zeros((1, 1), dtype=wp.vec3, device=dev)   # filled by analytic/moving.py's corner_table
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


def instant_frames(lights: np.ndarray, times: int) -> np.ndarray:
    """(NL * B, 12) float32: each light's local axes (rows x, y, z) and origin in camera space at
    map instant b = (b + 0.5) / B, from the tables at knots over the shutter (L+1, NL, W), read
    as the kernels read them (light_table.light_value, shadow_lookup.light_axes). One knot (a
    sharp instant's table): the same rows at every b, computed once."""
    segments = lights.shape[0] - 1
    nl = lights.shape[1]
    out = np.zeros((max(nl * times, 1), 12), np.float32)
    for b in range(times if segments > 0 else 1):
        u = (b + 0.5) / times
        if segments == 0:
            row = lights[0].astype(np.float32)
        else:
            x = min(max(u, 0.0), 1.0) * segments
            k = min(int(x), segments - 1)
            f = np.float32(x - k)
            row = lights[k].astype(np.float32) * (np.float32(1) - f) + lights[k + 1].astype(np.float32) * f
        for j in range(nl):
            ax = row[j, 10:13] / max(np.linalg.norm(row[j, 10:13]), 1e-30)
            ay = row[j, 13:16] - np.dot(row[j, 13:16], ax) * ax
            ay = ay / max(np.linalg.norm(ay), 1e-30)
            out[j * times + b, 0:9] = np.concatenate([ax, ay, np.cross(ax, ay)])
            out[j * times + b, 9:12] = row[j, 4:7]
    if segments == 0 and nl:
        out[:nl * times] = np.repeat(out[0:nl * times:times], times, axis=0)
    return out


def texture_arrays(textures, device: str) -> Textures:
    """The frame's textures (a textures.TextureSet, or None) on the device, uploaded once. Safe
    from two threads (a frame's shading is made beside its geometry): a Textures is published only
    once every array is in it."""
    with _TEXTURES_LOCK:
        if textures is None:
            from ..usd.textures import TextureSet
            textures = _NO_TEXTURES.setdefault(device, TextureSet())
        cached = textures.device_arrays.get(device)
        if cached is None:
            levels, tex, bindings = textures.index_arrays()
            cached = Textures()
            cached.texels = _texel_atlas(textures, device)
            cached.levels = wp.array(levels, dtype=int, device=device)
            cached.textures = wp.array(tex, dtype=int, device=device)
            cached.bindings = wp.array(bindings, dtype=float, device=device)
            textures.device_arrays[device] = cached
        return cached


def _texel_atlas(textures, device: str) -> wp.array:
    """The texel atlas of a TextureSet on the device. A stage's frames each build their own
    TextureSet from the same images, so the last few atlases are kept by what they hold
    (TextureSet.texel_key): a frame that reads the images of an earlier one uploads nothing
    (McUsd: 0.1 s a frame at 640×480). Called under _TEXTURES_LOCK."""
    key = (device, textures.texel_key)
    atlas = _TEXEL_ATLASES.get(key)
    if atlas is None:
        atlas = wp.array(textures.texel_atlas(), dtype=wp.vec4, device=device)
        _TEXEL_ATLASES[key] = atlas
        while len(_TEXEL_ATLASES) > TEXEL_ATLASES_KEPT:
            _TEXEL_ATLASES.popitem(last=False)
    else:
        _TEXEL_ATLASES.move_to_end(key)
    return atlas


_TEXTURES_LOCK = threading.Lock()
#: texel atlases kept on the devices, most recently used last (a stage's textures, a few stages')
TEXEL_ATLASES_KEPT = 4
_TEXEL_ATLASES: OrderedDict = OrderedDict()


_NO_TEXTURES: dict = {}
_NO_DOME_SH: dict = {}
_NO_FLAGS: dict = {}
_MATERIALS: dict = {}


def _no_flags(device: str) -> wp.array:
    """A one-element zero flag array (no entry flagged), shared per device."""
    return _NO_FLAGS.get(device) or _NO_FLAGS.setdefault(device, wp.zeros(1, dtype=int, device=device))


def _materials_array(materials: np.ndarray, device: str) -> wp.array:
    """The material table on the device, uploaded once while the same table object is shaded
    (a frame's sharp instants all share its table)."""
    cached = _MATERIALS.get(device)
    if cached is None or cached[0] is not materials:
        cached = _MATERIALS[device] = (materials, wp.array(np.ascontiguousarray(materials, np.float32), dtype=float,
                                                           device=device))
    return cached[1]


def make_shading(materials: np.ndarray, lights: np.ndarray, dome: np.ndarray, device: str,
                 shadows=None, options=None, textures=None, dome_frame=None, instant_major: bool = False,
                 instant_flags: bool = False) -> Shading:
    """lights: (L+1, NL, LIGHT_WIDTH) tables at L+1 knots over the shutter; shadows: a
    shadows.layout.ShadowData (or None: no light casts shadows) with its ShadowOptions; textures:
    the frame's textures.TextureSet (None: none); dome_frame: a textured dome as
    (binding, camera-to-dome rotations (R+1, 3, 3) for column vectors at even knots over the
    shutter (one when it holds), irradiance SH (9, 3), lod), or None. instant_major: the maps'
    memory holds each map instant's depth image whole (for a sharp instant, which reads one or
    two of them) instead of each texel's instants side by side (for shading at many times per
    pixel); the kernels index both alike (see shadow_map_array). instant_flags (with
    instant_major): the maps' varying-texel flags too, which a sharp instant reads only to find
    the still pixels whose shadows never change (accumulation.py; they cost tens of ms of NumPy)."""
    s = Shading()
    s.tex = texture_arrays(textures, device)
    if dome_frame is None:
        s.dome_binding, s.dome_rot, s.dome_lod = -1, wp.mat33(np.eye(3, dtype=np.float32)), 0.0
        s.dome_sh = _NO_DOME_SH.get(device) or _NO_DOME_SH.setdefault(device, wp.zeros(9, dtype=wp.vec3,
                                                                                          device=device))
        rots = np.eye(3, dtype=np.float32)[None]
    else:
        binding, rots, coeffs, lod = dome_frame
        rots = np.asarray(rots, np.float32).reshape(-1, 3, 3)
        if (rots == rots[:1]).all():
            rots = rots[:1]
        centre = rots[len(rots) // 2] if len(rots) % 2 else 0.5 * (rots[len(rots) // 2 - 1] + rots[len(rots) // 2])
        s.dome_binding, s.dome_rot, s.dome_lod = int(binding), wp.mat33(centre), float(lod)
        s.dome_sh = wp.array(np.ascontiguousarray(coeffs, np.float32), dtype=wp.vec3, device=device)
    s.dome_rots = wp.array(np.ascontiguousarray(rots), dtype=wp.mat33, device=device)
    s.dome_segments = len(rots) - 1
    s.materials = _materials_array(materials, device)
    nl = lights.shape[1]
    lt = lights if nl else np.zeros((lights.shape[0], 1, lights.shape[2]), np.float32)
    s.lights = wp.array(np.ascontiguousarray(lt, np.float32), dtype=float, device=device)
    s.num_lights = nl
    s.light_segments = lights.shape[0] - 1
    s.dome = wp.vec3(*[float(x) for x in dome])
    # per light: first map (-1 = no shadow), light samples, faces, 1 when the light holds still
    # over the shutter (its maps' texel flags then tell where a time span needs one lookup)
    if shadows is None:
        s.shadow_maps = wp.zeros((1, 1, 1, 1), dtype=float, device=device)
        s.shadow_varying = wp.zeros((1, 1, 1), dtype=wp.uint8, device=device)
        s.shadow_faces = wp.zeros((1, FACE_WIDTH), dtype=float, device=device)
        info = np.full((max(nl, 1), 4), -1, np.int32)
        s.shadow_lights = wp.array(info, dtype=int, device=device)
        s.shadow_times, s.shadow_size = 1, 1
        s.shadow_frames = wp.zeros((1, 12), dtype=float, device=device)
    else:
        # maps shared by many instants (accumulation) are uploaded once, not once per instant
        key = (device, instant_major, instant_major and instant_flags)
        cached = shadows.device_arrays.get(key)
        laid = shadows.texel_major if not instant_major else None
        if cached is None and laid is not None:
            # laid out while the maps rendered (shadows/texel_major.py): the CPU reads it as it is
            faces, slot_lights = slot_faces(shadows)
            on_host = wp.get_device(device).is_cpu
            dev_maps = laid.array if on_host else wp.array(laid.slots, dtype=float, device=device)
            dev_varying = laid.varying_array if on_host else wp.array(laid.varying, dtype=wp.uint8, device=device)
            if shadows.counters is not None:
                shadows.counters["shadow_texels_varying"] = float(laid.varying.mean()) if laid.varying.size else 0.0
            cached = (dev_maps, dev_varying, wp.array(faces, dtype=float, device=device), slot_lights)
            shadows.device_arrays[key] = cached
        if cached is None:
            # on the CPU the maps are laid out straight into the device array (no second copy)
            on_host = wp.get_device(device).is_cpu
            shape = slot_map_shape(shadows, instant_major)
            # on the CPU, a kept array (core/reuse.py): new memory faulted in 50 MB a frame on demo
            dev_maps = reused_empty(shape, float) if on_host else wp.empty(shape, dtype=float, device=device)
            maps, faces, varying, slot_lights = face_slots(shadows, dev_maps.numpy() if on_host else None,
                                                           instant_major, instant_flags)
            if not on_host:
                dev_maps.assign(maps)
            varying = varying if varying is not None else np.ones((1, 1, 1), np.uint8)
            cached = (shadow_map_array(dev_maps, instant_major), wp.array(varying, dtype=wp.uint8, device=device),
                      wp.array(faces, dtype=float, device=device), slot_lights)
            shadows.device_arrays[key] = cached
        s.shadow_maps, s.shadow_varying, s.shadow_faces, slot_lights = cached
        info = np.zeros((len(shadows.lights), 4), np.int32)
        info[:, :3] = slot_lights
        if shadows.times > 1 and not instant_major:   # (a sharp instant never looks up a span)
            info[:nl, 3] = (lt == lt[:1]).all(axis=(0, 2))[:nl]
        s.shadow_lights = wp.array(info, dtype=int, device=device)
        s.shadow_times, s.shadow_size = shadows.times, shadows.size
        s.shadow_frames = wp.array(instant_frames(lt, shadows.times), dtype=float, device=device)
    s.shadow_bias = float(options.bias) if options is not None else 1.0
    s.shadow_normal_bias = float(options.normal_bias) if options is not None else 1.5
    s.shadow_pcf = int(options.pcf) if options is not None else 0
    s.shadow_nearest = 0
    return s


def slot_map_shape(data, instant_major: bool = False) -> tuple[int, int, int, int]:
    """Shape (slots, S, S, B) of face_slots' maps for a frame's ShadowData ((slots, B, S, S) in
    memory when instant_major)."""
    slots = max(sum(int(m * f) for first, m, f in data.lights if first >= 0), 1)
    if instant_major:
        return (slots, data.times, data.size, data.size)
    return (slots, data.size, data.size, data.times)


def shadow_map_array(maps: wp.array, instant_major: bool) -> wp.array:
    """The kernels' (slots, S, S, B) view of maps laid out by face_slots: the array itself, or a
    strided view of an instant-major (slots, B, S, S) array (the kernels index both the same way,
    shadow_maps[slot, y, x, b]; the view holds `maps`, which owns the memory)."""
    if not instant_major:
        return maps
    slots, b, s, _ = maps.shape
    item = 4   # float32
    view = wp.array(ptr=maps.ptr, shape=(slots, s, s, b), strides=(b * s * s * item, s * item, item, s * s * item),
                    dtype=float, device=maps.device)
    view.owner_array = maps   # a view made from a pointer does not keep its memory alive by itself
    return view


def slot_faces(data) -> tuple[np.ndarray, np.ndarray]:
    """(faces (slots, FACE_WIDTH), lights (NL, 3) [first slot or -1, samples, faces]) of a frame's
    maps (a shadows.layout.ShadowData): slot first + m F + f is light sample m, face f (the
    face rows of one slot are the same at every instant)."""
    b = data.times
    faces = np.zeros((slot_map_shape(data)[0], data.faces.shape[1]), np.float32)
    lights = data.lights.copy()
    k = 0
    for j, (first, m, f) in enumerate(data.lights):
        if first < 0:
            continue
        width = data.faces.shape[1]   # (explicit: a light may have no faces, and -1 then has no size)
        faces[k:k + m * f] = data.faces[first:first + m * b * f].reshape(m, b, f, width)[:, 0].reshape(m * f, width)
        lights[j, 0] = k
        k += m * f
    return faces, lights


def face_slots(data, out: np.ndarray | None = None, instant_major: bool = False,
               instant_flags: bool = False) -> tuple[np.ndarray, np.ndarray, np.ndarray | None, np.ndarray]:
    """The kernels' layout of a frame's maps (a shadows.layout.ShadowData): (maps (slots, S, S, B)
    float32 with each face's B instants side by side, or (slots, B, S, S) with each instant's image
    whole when instant_major, written into `out` when given, faces and lights (slot_faces),
    varying (slots, S, S) uint8 or None (one instant, or instant_major without instant_flags))."""
    b, s = data.times, data.size
    shape = slot_map_shape(data, instant_major)
    maps = out if out is not None else np.empty(shape, np.float32)
    faces, lights = slot_faces(data)
    varying = np.zeros((shape[0], s, s), np.uint8) if b > 1 and (instant_flags or not instant_major) else None
    for (first, m, f), k in zip(data.lights, lights[:, 0]):
        if first < 0:
            continue
        n = m * b * f
        block = data.instant_maps()[first:first + n].reshape(m, b, f, s, s)
        if instant_major:
            maps[k:k + m * f].reshape(m, f, b, s, s)[...] = block.transpose(0, 2, 1, 3, 4)
        else:
            maps[k:k + m * f].reshape(m, f, s, s, b)[...] = block.transpose(0, 2, 3, 4, 1)   # no temporary
        if varying is not None:   # flags for spans of time, and for instants that look alike
            varying[k:k + m * f] = data.varying[first:first + n].reshape(m, b, f, s, s)[:, 0].reshape(m * f, s, s)
    return maps, faces, varying, lights


def make_bins(bins: TileBins, device: str) -> Bins:
    b = Bins()
    b.tile_offsets = device_array(bins.tile_offsets, int, device)
    b.tile_entries = device_array(bins.tile_entries, int, device)
    boxes = bins.entry_boxes if bins.entry_boxes is not None else np.zeros((0, 4), np.float32)
    b.entry_boxes = device_array(boxes.astype(np.float32), wp.vec4, device)
    bands = bins.entry_bands
    if bands is None:   # no slab reject: one pass-all slab each
        bands = pass_all_slabs(len(boxes))
    b.entry_bands = device_array(bands.astype(np.float32), wp.vec4, device)   # (E, S) slabs
    near = bins.entry_near if bins.entry_near is not None else np.zeros(0, np.float32)
    b.entry_near = device_array(near.astype(np.float32), float, device)
    b.near_sorted = 1 if bins.entry_near is not None else 0
    return b

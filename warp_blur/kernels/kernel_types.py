"""Warp structs shared by every kernel: the view, the geometry over time, shading inputs, tile bins.

Geometry over time: vertex positions are stored at K+1 knots over the shutter (u = k/K). An *entry*
is a triangle over a span of knots [k0, k1]: its vertices move linearly from knot k0 to k1 for
u in [k0/K, k1/K]. An entry with k0 == k1 is static: the same triangle for every u in [0, 1].
The sharp render is the special case of static entries.
"""

from __future__ import annotations

import warp as wp

from ..core import warp_setup  # noqa: F401  (Warp's settings, before anything starts it)


@wp.struct
class View:
    """Image and camera: window on the reference plane (distance 1, or scene units if ortho)."""

    width: int
    height: int
    win_min: wp.vec2
    win_max: wp.vec2
    ortho: int
    near: float
    far: float
    spatial: int          # n -> n×n sub-pixel positions (1 = pixel centre)
    tile_size: int
    tiles_x: int


@wp.struct
class Textures:
    """Every texture of the frame (textures.py's layout), read by shading and by cutout tests."""

    texels: wp.array(dtype=wp.vec4)      # all mip levels, linear RGBA
    levels: wp.array2d(dtype=int)        # (levels, 3) offset, width, height
    textures: wp.array2d(dtype=int)      # (textures, 4) first level, level count, wrapS, wrapT
    bindings: wp.array2d(dtype=float)    # (bindings, 10) texture, channel, scale rgba, bias rgba


@wp.struct
class Geometry:
    """Camera-space triangles over the shutter (see module docstring)."""

    positions: wp.array2d(dtype=wp.vec3)    # (K+1, V)
    normals: wp.array2d(dtype=wp.vec3)      # (K+1, V) smooth vertex normals, or (1, 1) unused
    tri_vertices: wp.array(dtype=wp.vec3i)  # (T,)
    tri_flags: wp.array(dtype=int)          # (T,) bit 0 double-sided, bit 1 smooth
    tri_material: wp.array(dtype=int)       # (T,)
    tri_colors: wp.array(dtype=wp.vec3)     # (3T,) colour primvar at corner k of triangle t (3t + k)
    tri_uvs: wp.array(dtype=wp.vec2)        # (3T,) texture coordinates at the corners, or (1,) untextured
    tri_lod: wp.array(dtype=float)          # (T,) log2 texture-coordinate span per pixel, or (1,) untextured
    entry_tri: wp.array(dtype=int)          # (E,)
    entry_k0: wp.array(dtype=int)           # (E,)
    entry_k1: wp.array(dtype=int)           # (E,)
    num_segments: int                       # K
    velocities: wp.array(dtype=wp.vec3)     # (V,) per-shutter vertex velocities of static entries, or (1,) unused
    has_velocities: int                     # 1 when `velocities` holds them (a sharp instant whose shadow maps are at other instants)
    tri_cutout: wp.array(dtype=wp.vec3)     # (T,) opacity test (code, threshold, opacity; cutout.py), or (1,) unused
    tri_alpha: wp.array(dtype=wp.vec3)      # (T,) corner opacities (code -4, cutout.py), or (1,) unused
    has_cutouts: int                        # 1 when some triangle has a cutout test (cutout.py)
    cutout_slots: int                       # time slots per shutter at which the analytic method tests a moving cutout
    presence_shift: int                     # added to fractional opacity's presence slot (cutout.py; 0 but in velocity passes)
    clip_bits: int                          # analytic time bits (0: exact): near/far crossings bisected to 1/16 of a slot
    tex: Textures                           # the frame's textures (for cutout opacity)
    shadow_free: wp.array(dtype=int)        # (E * NL,) [e NL + j] bit c: light j's maps cast no shadow on cell c of entry e (shadow_free.py); (1,) 0: none
    entry_edges: wp.array2d(dtype=wp.vec3)  # (E, 11) a moving entry's edge quadratics for rays from the eye (analytic/coverage.py), or (1, 1) unused
    entry_corners: wp.array2d(dtype=wp.vec3)  # (E, 6) entry e's vertices a, b, c at k0 then at k1, side by side (analytic/moving.py), or (1, 1) unused


@wp.struct
class Shading:
    """Materials (M, 24; materials.py), lights at L+1 knots (L+1, NL, 18), the dome radiance, and shadow maps.

    Shadow maps (see shadow_lookup.py): shadow_maps (slots, S, S, B) depth along each face's
    view axis at the B = shadow_times map instants (instant b at shutter time (b + 0.5) / B);
    shadow_faces (slots, FACE_WIDTH) face rotation rows, light-sample offset, window, ortho flag;
    shadow_lights (NL, 4) per light: first slot (-1 = casts no shadow), light samples M, faces F,
    1 when the light holds still (then shadow_varying (slots, S, S) flags the texels whose depth
    changes over the instants). Light j's sample m, face f is slot first + m * F + f.
    """

    materials: wp.array2d(dtype=float)
    lights: wp.array3d(dtype=float)
    num_lights: int
    light_segments: int
    dome: wp.vec3                            # uniform dome radiance (a textured dome's mean)
    dome_binding: int                        # textured dome: its map's texture binding (dome.py), else -1
    dome_rot: wp.mat33                       # camera-space directions -> dome directions (shutter centre)
    dome_rots: wp.array(dtype=wp.mat33)      # (R+1,) dome_rot at R+1 even knots over the shutter (a turning camera)
    dome_segments: int                       # R: 0 when the camera's orientation holds (dome_rot throughout)
    dome_sh: wp.array(dtype=wp.vec3)         # (9,) SH coefficients of the dome's irradiance (dome space)
    dome_lod: float                          # log2 of a pixel's angle / 2 pi (the map's mip level)
    shadow_maps: wp.array4d(dtype=float)
    shadow_varying: wp.array3d(dtype=wp.uint8)
    shadow_faces: wp.array2d(dtype=float)
    shadow_lights: wp.array2d(dtype=int)
    shadow_frames: wp.array2d(dtype=float)   # (NL * B, 12) light j's axes rows and origin at map instant b (row j B + b)
    shadow_times: int
    shadow_size: int
    shadow_bias: float         # depth bias, in texels (world size of a texel at the receiver)
    shadow_normal_bias: float  # receiver offset along its normal, in texels
    shadow_pcf: int            # PCF radius in texels (0 = bilinear 2x2)
    shadow_nearest: int        # 1: a lookup at time u reads the nearest map instant, not a blend of two
    tex: Textures


@wp.struct
class Bins:
    """Entries overlapping each screen tile: tile_entries[tile_offsets[t]:tile_offsets[t+1]], and
    each entry's swept pixel box and swept slabs (binning.swept_bands) for a cheap per-pixel reject."""

    tile_offsets: wp.array(dtype=int)
    tile_entries: wp.array(dtype=int)
    entry_boxes: wp.array(dtype=wp.vec4)    # (E,) swept pixel box (x0, y0, x1, y1) of each entry
    entry_bands: wp.array2d(dtype=wp.vec4)  # (E, S) swept slabs (nx, ny, lo, hi): across its motion, along its edges
    entry_near: wp.array(dtype=float)       # (E,) view depth bound the lists ascend in (binning.TileBins)
    near_sorted: int                        # 1: the lists ascend in entry_near; 0: entry order (entry_near unused)

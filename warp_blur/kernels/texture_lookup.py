"""Filtered texture lookups in the kernels (layout: textures.py): bilinear within a mip level,
linear between the two levels around the triangle's level of detail (trilinear), USD's wrap
modes, UsdUVTexture's scale and bias, and the output channel a material input reads."""

from __future__ import annotations

import warp as wp

from .kernel_types import Shading


@wp.func
def wrap_index(i: int, n: int, mode: int) -> int:
    """Texel index i wrapped into [0, n) by mode (0 repeat, 1 mirror, 2 clamp), or -1 (3 black) outside."""
    if i >= 0 and i < n:
        return i
    if mode == 0:
        return ((i % n) + n) % n
    if mode == 1:
        p = ((i % (2 * n)) + 2 * n) % (2 * n)
        if p >= n:
            p = 2 * n - 1 - p
        return p
    if mode == 2:
        return wp.clamp(i, 0, n - 1)
    return -1


@wp.func
def texel(sh: Shading, level: int, x: int, y: int, wrap_s: int, wrap_t: int) -> wp.vec4:
    w = sh.tex_levels[level, 1]
    h = sh.tex_levels[level, 2]
    xi = wrap_index(x, w, wrap_s)
    yi = wrap_index(y, h, wrap_t)
    if xi < 0 or yi < 0:
        return wp.vec4(0.0, 0.0, 0.0, 0.0)
    return sh.tex_texels[sh.tex_levels[level, 0] + yi * w + xi]


@wp.func
def bilinear(sh: Shading, level: int, uv: wp.vec2, wrap_s: int, wrap_t: int) -> wp.vec4:
    """Texel-centre bilinear lookup; uv in USD's convention (t = 0 at the image's bottom row)."""
    w = float(sh.tex_levels[level, 1])
    h = float(sh.tex_levels[level, 2])
    x = uv[0] * w - 0.5
    y = (1.0 - uv[1]) * h - 0.5
    x0 = wp.floor(x)
    y0 = wp.floor(y)
    fx = x - x0
    fy = y - y0
    ix = int(x0)
    iy = int(y0)
    a = texel(sh, level, ix, iy, wrap_s, wrap_t)
    b = texel(sh, level, ix + 1, iy, wrap_s, wrap_t)
    c = texel(sh, level, ix, iy + 1, wrap_s, wrap_t)
    d = texel(sh, level, ix + 1, iy + 1, wrap_s, wrap_t)
    return (a * (1.0 - fx) + b * fx) * (1.0 - fy) + (c * (1.0 - fx) + d * fx) * fy


@wp.func
def sample_texture(sh: Shading, tex: int, uv: wp.vec2, lod: float) -> wp.vec4:
    """Trilinear lookup of texture tex at mip level `lod` (0 = full resolution)."""
    first = sh.tex_textures[tex, 0]
    count = sh.tex_textures[tex, 1]
    ws = sh.tex_textures[tex, 2]
    wt = sh.tex_textures[tex, 3]
    l = wp.clamp(lod, 0.0, float(count - 1))
    l0 = int(wp.floor(l))
    f = l - float(l0)
    out = bilinear(sh, first + l0, uv, ws, wt)
    if f > 0.0 and l0 + 1 < count:
        out = out * (1.0 - f) + bilinear(sh, first + l0 + 1, uv, ws, wt) * f
    return out


@wp.func
def binding_value(sh: Shading, b: int, uv: wp.vec2, lod_base: float) -> wp.vec3:
    """A material input read from binding b: rgb for output 'rgb', else the one channel in x, y, z.
    lod_base is log2 of the surface's texture-coordinate span per pixel (textures.py)."""
    tex = int(sh.tex_bindings[b, 0])
    channel = int(sh.tex_bindings[b, 1])
    first = sh.tex_textures[tex, 0]
    side = float(wp.max(sh.tex_levels[first, 1], sh.tex_levels[first, 2]))
    c = sample_texture(sh, tex, uv, lod_base + wp.log2(side))
    v = wp.vec4(c[0] * sh.tex_bindings[b, 2] + sh.tex_bindings[b, 6], c[1] * sh.tex_bindings[b, 3] + sh.tex_bindings[b, 7],
                c[2] * sh.tex_bindings[b, 4] + sh.tex_bindings[b, 8], c[3] * sh.tex_bindings[b, 5] + sh.tex_bindings[b, 9])
    if channel == 0:
        return wp.vec3(v[0], v[1], v[2])
    s = v[channel - 1]
    return wp.vec3(s, s, s)

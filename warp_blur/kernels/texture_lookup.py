"""Filtered texture lookups in the kernels (layout: textures.py): bilinear within a mip level,
linear between the two levels around the triangle's level of detail (trilinear), USD's wrap
modes, UsdUVTexture's scale and bias, and the output channel a material input reads."""

from __future__ import annotations

import warp as wp

from .kernel_types import Textures


@wp.func
def wrap_index(i: int, n: int, mode: int) -> int:
    """Texel index i wrapped into [0, n) by mode (0 repeat, 1 mirror, 2 clamp), or -1 (3 black) outside."""
    if i >= 0 and i < n:
        return i
    if mode == 0:
        # within a period of the texture (uv in [-1, 2)): no integer division
        if i < 0 and i >= -n:
            return i + n
        if i >= n and i < 2 * n:
            return i - n
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
def texel_at(tx: Textures, base: int, w: int, xi: int, yi: int) -> wp.vec4:
    """Texel (xi, yi) of the level whose first texel is base and width w; black where an index
    is -1 (wrap_index's black border)."""
    if xi < 0 or yi < 0:
        return wp.vec4(0.0, 0.0, 0.0, 0.0)
    return tx.texels[base + yi * w + xi]


@wp.func
def bilinear(tx: Textures, level: int, uv: wp.vec2, wrap_s: int, wrap_t: int) -> wp.vec4:
    """Texel-centre bilinear lookup; uv in USD's convention (t = 0 at the image's bottom row).
    The four texels are read directly where they lie inside the level (the common case), and
    through the wrap modes at its border."""
    base = tx.levels[level, 0]
    wi = tx.levels[level, 1]
    hi = tx.levels[level, 2]
    w = float(wi)
    h = float(hi)
    x = uv[0] * w - 0.5
    y = (1.0 - uv[1]) * h - 0.5
    x0 = wp.floor(x)
    y0 = wp.floor(y)
    fx = x - x0
    fy = y - y0
    ix = int(x0)
    iy = int(y0)
    # repeat is periodic: a texel column or row a whole number of periods away reads the same
    # texels, so uv outside [0, 1] (glTF's tiled faces) still takes the direct reads below
    if wrap_s == 0 and (ix < 0 or ix >= wi):
        ix = wrap_index(ix, wi, 0)
    if wrap_t == 0 and (iy < 0 or iy >= hi):
        iy = wrap_index(iy, hi, 0)
    a = wp.vec4()
    b = wp.vec4()
    c = wp.vec4()
    d = wp.vec4()
    if ix >= 0 and ix + 1 < wi and iy >= 0 and iy + 1 < hi:
        k = base + iy * wi + ix
        a = tx.texels[k]
        b = tx.texels[k + 1]
        c = tx.texels[k + wi]
        d = tx.texels[k + wi + 1]
    else:
        x_0 = wrap_index(ix, wi, wrap_s)
        x_1 = wrap_index(ix + 1, wi, wrap_s)
        y_0 = wrap_index(iy, hi, wrap_t)
        y_1 = wrap_index(iy + 1, hi, wrap_t)
        a = texel_at(tx, base, wi, x_0, y_0)
        b = texel_at(tx, base, wi, x_1, y_0)
        c = texel_at(tx, base, wi, x_0, y_1)
        d = texel_at(tx, base, wi, x_1, y_1)
    return (a * (1.0 - fx) + b * fx) * (1.0 - fy) + (c * (1.0 - fx) + d * fx) * fy


@wp.func
def sample_texture(tx: Textures, tex: int, uv: wp.vec2, lod: float) -> wp.vec4:
    """Trilinear lookup of texture tex at mip level `lod` (0 = full resolution)."""
    first = tx.textures[tex, 0]
    count = tx.textures[tex, 1]
    ws = tx.textures[tex, 2]
    wt = tx.textures[tex, 3]
    l = wp.clamp(lod, 0.0, float(count - 1))
    l0 = int(wp.floor(l))
    f = l - float(l0)
    out = bilinear(tx, first + l0, uv, ws, wt)
    if f > 0.0 and l0 + 1 < count:
        out = out * (1.0 - f) + bilinear(tx, first + l0 + 1, uv, ws, wt) * f
    return out


@wp.func
def binding_sample(tx: Textures, b: int, uv: wp.vec2, lod_base: float) -> wp.vec4:
    """The filtered texture sample binding b reads at surface coordinates uv (its transform, UDIM
    tile and level applied), before its scale, bias and output channel. lod_base is log2 of the
    surface's texture-coordinate span per pixel (textures.py)."""
    tex = int(tx.bindings[b, 0])
    # a UsdTransform2d between the primvar and the texture (identity when none)
    st = wp.vec2(tx.bindings[b, 11] * uv[0] + tx.bindings[b, 12] * uv[1] + tx.bindings[b, 15],
                 tx.bindings[b, 13] * uv[0] + tx.bindings[b, 14] * uv[1] + tx.bindings[b, 16])
    if tx.bindings[b, 10] > 0.5:   # UDIM: tile 1001 + u + 10 v, read at the coordinates within it
        fu = wp.floor(st[0])
        fv = wp.floor(st[1])
        tex = tex + wp.clamp(int(fu), 0, 9) + 10 * wp.clamp(int(fv), 0, 9)
        st = wp.vec2(st[0] - fu, st[1] - fv)
    first = tx.textures[tex, 0]
    side = float(wp.max(tx.levels[first, 1], tx.levels[first, 2]))
    return sample_texture(tx, tex, st, lod_base + tx.bindings[b, 17] + wp.log2(side))


@wp.func
def binding_output(tx: Textures, b: int, c: wp.vec4) -> wp.vec3:
    """Binding b's value from its texture sample c: rgb for output 'rgb', else the one channel in
    x, y, z (scale and bias applied)."""
    channel = int(tx.bindings[b, 1])
    v = wp.vec4(c[0] * tx.bindings[b, 2] + tx.bindings[b, 6], c[1] * tx.bindings[b, 3] + tx.bindings[b, 7],
                c[2] * tx.bindings[b, 4] + tx.bindings[b, 8], c[3] * tx.bindings[b, 5] + tx.bindings[b, 9])
    if channel == 0:
        return wp.vec3(v[0], v[1], v[2])
    s = v[channel - 1]
    return wp.vec3(s, s, s)


@wp.func
def binding_value(tx: Textures, b: int, uv: wp.vec2, lod_base: float) -> wp.vec3:
    """A material input read from binding b at surface coordinates uv: rgb for output 'rgb', else
    the one channel in x, y, z."""
    return binding_output(tx, b, binding_sample(tx, b, uv, lod_base))


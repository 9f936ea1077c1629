"""Back faces that cannot show, dropped before the camera's visibility (shadow maps leave theirs out
with instance_volume_sign too, the light as the eye: shadows/direct.py, FaceRasterizer.cull_signs).

A triangle of a closed, consistently oriented, opaque surface (scene.tri_closed) is hidden by the
same surface's front faces wherever it faces away from the eye, provided the eye is outside the
surface: here, every vertex of that prim instance lies within the clipping range at every knot
(so no near-plane cut opens it and the eye, at depth 0, is outside it). Facing over a linear span
is the sign of det(a(t), b(t), c(t)) with the eye at the origin, a cubic in t whose four
Bernstein coefficients bound it: the triangle is dropped when all four have the back-facing sign
(the sign of the instance's signed volume, so inward-wound and mirrored surfaces work alike).
Dropping them leaves every image unchanged and halves the coverage work on closed meshes.
The determinants are float64 Warp kernels on the CPU, where the data is (NumPy's temporaries made
them 34 ms a frame on `large`'s 70 k triangles; 8 ms now).
"""

from __future__ import annotations

import numpy as np
import warp as wp

from ..core import warp_setup  # noqa: F401  (Warp's settings, before anything starts it)
from ..core.host_arrays import int32_array, vec3d_array, vec3i_array
from ..core.parallel import launch_cheap
from ..core.rows import all_corners


@wp.func
def det3(a: wp.vec3d, b: wp.vec3d, c: wp.vec3d) -> wp.float64:
    """det[a, b, c] = a · (b × c), written out by components."""
    return (a[0] * (b[1] * c[2] - b[2] * c[1]) + a[1] * (b[2] * c[0] - b[0] * c[2])
            + a[2] * (b[0] * c[1] - b[1] * c[0]))


@wp.kernel(enable_backward=False)
def triangle_dets(positions: wp.array2d(dtype=wp.vec3d), tri_vertices: wp.array(dtype=wp.vec3i),
                  tris: wp.array(dtype=wp.int32), first: int,
                  # output
                  dets: wp.array2d(dtype=wp.float64)):
    """dets[k, i] = det[a, b, c] of triangle tris[i]'s vertices at every knot k (positions
    (K+1, V)), for i = first + tid (launched over bands of triangles)."""
    i = first + wp.tid()
    vi = tri_vertices[tris[i]]
    for k in range(positions.shape[0]):
        dets[k, i] = det3(positions[k, vi[0]], positions[k, vi[1]], positions[k, vi[2]])


@wp.kernel(enable_backward=False)
def back_facing_spans(positions: wp.array2d(dtype=wp.vec3d), tri_vertices: wp.array(dtype=wp.vec3i),
                      entry_tri: wp.array(dtype=wp.int32), entry_k0: wp.array(dtype=wp.int32),
                      entry_k1: wp.array(dtype=wp.int32), sign: wp.array(dtype=wp.float64),
                      # output
                      back: wp.array(dtype=wp.int8)):
    """back[i] = 1 when all four Bernstein coefficients of det[a(t), b(t), c(t)] over entry i's span
    (triangle entry_tri[i] moving linearly from knot entry_k0[i] to entry_k1[i]) have sign[i]."""
    i = wp.tid()
    vi = tri_vertices[entry_tri[i]]
    k0 = entry_k0[i]
    k1 = entry_k1[i]
    a0 = positions[k0, vi[0]]
    b0 = positions[k0, vi[1]]
    c0 = positions[k0, vi[2]]
    a1 = positions[k1, vi[0]]
    b1 = positions[k1, vi[1]]
    c1 = positions[k1, vi[2]]
    s = sign[i]
    third = wp.float64(1.0) / wp.float64(3.0)
    zero = wp.float64(0.0)
    out = wp.int8(0)
    if det3(a0, b0, c0) * s > zero and det3(a1, b1, c1) * s > zero:
        if (det3(a1, b0, c0) + det3(a0, b1, c0) + det3(a0, b0, c1)) * third * s > zero:
            if (det3(a1, b1, c0) + det3(a1, b0, c1) + det3(a0, b1, c1)) * third * s > zero:
                out = wp.int8(1)
    back[i] = out


def instance_volume_sign(positions: np.ndarray, tri_vertices: np.ndarray, tri_object: np.ndarray,
                         closed: np.ndarray, near: float, far: float) -> np.ndarray:
    """(objects,) +1 / -1: the sign of each closed instance's signed volume, the same at every
    knot of positions (K+1, V, 3) (camera space), with all its vertices within [near, far] at
    every knot; 0 where back faces may show (open, clipped, or degenerate)."""
    n_obj = int(tri_object.max()) + 1 if len(tri_object) else 0
    ok = np.zeros(n_obj, bool)
    ok[tri_object[closed]] = True
    depth = -positions[..., 2]
    inside = all_corners((depth.min(axis=0) >= near) & (depth.max(axis=0) <= far), tri_vertices)   # (T,)
    ok[tri_object[~(inside & closed)]] = False   # an instance with any open or clipped triangle
    sign = np.zeros(n_obj)
    first = None
    tris = np.nonzero(closed)[0]                             # open instances are already out
    obj = tri_object[tris]
    dets = np.zeros((positions.shape[0], len(tris)))
    if len(tris):
        inputs = [vec3d_array(positions), vec3i_array(tri_vertices), int32_array(tris)]
        out = wp.array(dets, dtype=wp.float64, device="cpu", copy=False)
        # (bands on every core for a field of instances; one launch for the few triangles of an
        # accumulation instant, which calls this at every instant)
        launch_cheap(triangle_dets, len(tris), lambda first, _n: [*inputs, first, out], "cpu")
    for k in range(positions.shape[0]):
        vol = np.bincount(obj, weights=dets[k], minlength=n_obj)
        s = np.sign(vol)
        first = s if first is None else first
        ok &= (s == first) & (s != 0)
    sign[ok] = first[ok]
    return sign


def hidden_back_faces(positions: np.ndarray, tri_vertices: np.ndarray, tri_object: np.ndarray, closed: np.ndarray,
                      entry_tri: np.ndarray, entry_k0: np.ndarray, entry_k1: np.ndarray, near: float, far: float,
                      orthographic: bool = False) -> np.ndarray:
    """(E,) bool: entries (triangle, span of knots k0..k1 over positions (K+1, V, 3), camera space)
    that face away from the eye over their whole span on a closed opaque instance the eye is
    outside of: they cannot show in the camera's view."""
    out = np.zeros(len(entry_tri), bool)
    if orthographic or len(entry_tri) == 0 or not closed.any():
        return out
    # signs only of the instances the entries belong to (a few moving ones of many, per instant)
    listed = np.zeros(int(tri_object.max()) + 1, bool)
    listed[tri_object[entry_tri]] = True
    sign = instance_volume_sign(positions, tri_vertices, tri_object, closed & listed[tri_object], near, far)
    s = sign[tri_object[entry_tri]]
    cand = np.nonzero(s != 0)[0]
    if len(cand) == 0:
        return out
    back = np.zeros(len(cand), np.int8)
    wp.launch(back_facing_spans, dim=len(cand),
              inputs=[vec3d_array(positions), vec3i_array(tri_vertices), int32_array(entry_tri[cand]),
                      int32_array(entry_k0[cand]), int32_array(entry_k1[cand]),
                      wp.array(s[cand], dtype=wp.float64, device="cpu")],
              outputs=[wp.array(back, dtype=wp.int8, device="cpu", copy=False)], device="cpu")
    out[cand] = back != 0
    return out

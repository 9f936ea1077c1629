"""Lights whose shadows can fall on nothing lit: no maps are made for them.

A shadow changes a pixel only where a caster comes between a light and a lit receiver. Looking along
a distant light, a caster can shadow a receiver only where their outlines across the beam overlap;
each object's outline is bounded by its extents along DIRECTIONS in the plane across the beam (a 2D
k-DOP). From a local light (sphere, disk, rect), a caster can shadow a receiver only where it meets
the hull of the receiver and the light, bounded by their extents along SOLID_DIRECTIONS, the light
taken as a ball of its reach (every sample point of its maps lies in it). Extents are taken over
every knot of the frame's motion plan: the maps see the scene only between consecutive knots,
linearly, and the knots' extents hold every such point. An object shadows itself only where it is
not a convex solid: the faces of a closed, convex, flat-shaded solid turned away from the light are
unlit by their own normal, and those are exactly the faces its maps would darken (a smooth-shaded or
normal-mapped one may light them through its shading normals, so it keeps its maps); it must be
convex at every knot. Emissive-only surfaces receive nothing. The test is conservative: a light is
dropped only when no (caster, receiver) pair can meet; lights that move, switch or change over the
shutter keep their maps.
"""

from __future__ import annotations

import numpy as np

from ..usd.lights import DISK, DISTANT, RECT
from ..usd.materials import COL_NORMAL_BINDING
from ..usd.units import FLAG_SMOOTH
from .layout import Sample, light_frame

#: tests switch this off to compare against building every shadowing light's maps
PAIR_CULLING = True
#: directions across a distant light's beam along which outlines are compared
DIRECTIONS = 8
#: directions along which objects and a local light's reach are compared (axes, face and cube
#: diagonals of camera space)
SOLID_DIRECTIONS = np.array([d for d in ((1, 0, 0), (0, 1, 0), (0, 0, 1), (1, 1, 0), (1, -1, 0), (1, 0, 1), (1, 0, -1),
                                         (0, 1, 1), (0, 1, -1), (1, 1, 1), (1, 1, -1), (1, -1, 1), (1, -1, -1))],
                            np.float64)
SOLID_DIRECTIONS /= np.linalg.norm(SOLID_DIRECTIONS, axis=1, keepdims=True)
#: objects beyond this many are not compared pair by pair (their maps are kept)
MAX_OBJECTS = 256
#: an object is checked for convexity only up to this many (faces × vertices, over all knots:
#: a larger flat closed mesh keeps its maps)
MAX_CONVEX_WORK = 4_000_000
#: values (knots × vertices × directions) the extents project in one pass: with accumulation's
#: instants as knots there may be a thousand of them
EXTENT_CHUNK = 4_000_000
#: a vertex this far (relative to the object's size) outside a face's plane makes it non-convex
CONVEX_TOL = 1e-6


def responds_to_light(material_table: np.ndarray) -> np.ndarray:
    """(M,) bool: materials whose surfaces reflect light (vertex colours, textures, a diffuse or
    specular colour): what a shadow can darken."""
    m = material_table
    return (m[:, 10] > 0.5) | (m[:, 21] > 0.5) | (np.abs(m[:, 0:3]).sum(axis=1) > 0) | (np.abs(m[:, 6:9]).sum(axis=1) > 0)


def is_convex_solid(positions: np.ndarray, tris: np.ndarray) -> bool:
    """True when every vertex of triangles tris ((F, 3) indices into positions (V, 3), or (K, V, 3):
    K shapes of one mesh, e.g. its knots) lies on one side of each of their planes (within
    CONVEX_TOL of the size) in every shape: a closed such surface bounds a convex solid. Too large
    a mesh to check (MAX_CONVEX_WORK, over all K), or one with no finite size, counts as not
    convex. The K shapes are checked in one NumPy pass (a pass each cost ~40 µs: accumulation's
    1024 instants times 256 receivers would have taken seconds)."""
    shapes = positions[None] if positions.ndim == 2 else positions
    verts, local = np.unique(tris, return_inverse=True)
    if len(tris) == 0 or len(tris) * len(verts) * len(shapes) > MAX_CONVEX_WORK:
        return False
    local = local.reshape(-1, 3)
    p = shapes[:, verts]   # (K, U, 3)
    with np.errstate(over="ignore", invalid="ignore"):
        centre = 0.5 * (p.min(axis=1) + p.max(axis=1))      # (K, 3)
        size = np.max(p.max(axis=1) - p.min(axis=1), axis=1)   # (K,)
    if not np.isfinite(size).all() or not (size > 0.0).all() or not np.isfinite(centre).all():
        return False
    q = (p - centre[:, None, :]) / size[:, None, None]   # each shape's own scale: no overflow, one tolerance
    a, b, c = q[:, local[:, 0]], q[:, local[:, 1]], q[:, local[:, 2]]   # (K, F, 3)
    n = np.cross(b - a, c - a)
    lengths = np.linalg.norm(n, axis=2)   # (K, F)
    use = lengths > 1e-12
    if not use.any(axis=1).all():
        return False
    side = np.einsum("kux,kfx->kfu", q, n) - np.einsum("kfx,kfx->kf", a, n)[:, :, None]   # (K, F, U), × |normal|
    tol = (CONVEX_TOL * lengths)[:, :, None]
    one_side = (side <= tol).all(axis=2) | (side >= -tol).all(axis=2)
    return bool((one_side | ~use).all())


def pair_receivers(scene) -> tuple[np.ndarray, np.ndarray] | None:
    """(tri_receives, tri_self_safe) of a usd.scene.Scene, (T,) bool each: the triangles whose
    material responds to light, and those of closed, opaque, flat-shaded prims without a normal
    map (a convex one cannot shadow itself on a lit face); None when PAIR_CULLING is off."""
    if not PAIR_CULLING:
        return None
    receives = responds_to_light(scene.material_table)[scene.tri_material]
    normal_mapped = (scene.material_table[:, COL_NORMAL_BINDING] >= 0)[scene.tri_material]
    return receives, scene.tri_closed & ((scene.tri_flags & FLAG_SMOOTH) == 0) & ~normal_mapped


def may_drop_lights(tri_visible: np.ndarray, tri_receives: np.ndarray, tri_self_safe: np.ndarray) -> bool:
    """False when unneeded_lights must keep every light of a scene whose visibility at one knot is
    tri_visible ((T,) bool, or empty: all): a lit triangle there may shadow itself."""
    visible = tri_visible if len(tri_visible) == len(tri_receives) else np.ones(len(tri_receives), bool)
    return not (visible & tri_receives & ~tri_self_safe).any()


def light_shadows_nothing(j: int, knots: list[Sample], tri_vertices: np.ndarray, tri_object: np.ndarray,
                          tri_receives: np.ndarray, tri_self_safe: np.ndarray) -> bool:
    """True when light row j can darken no lit surface of the scene given at the plan's knots
    (unneeded_lights for one light)."""
    return j in unneeded_lights([j], knots, tri_vertices, tri_object, tri_receives, tri_self_safe)


def unneeded_lights(rows: list[int], knots: list[Sample], tri_vertices: np.ndarray, tri_object: np.ndarray,
                    tri_receives: np.ndarray, tri_self_safe: np.ndarray) -> set[int]:
    """The light rows of `rows` that can darken no lit surface of the scene given at the plan's
    knots: no object meets the region a receiving object's shadows come from (across a distant
    light's beam, its outline; from a local light, its hull with the light), and each receiving
    object is a convex solid (tri_self_safe: closed, opaque, flat-shaded, no normal map; checked
    convex here). tri_receives: (T,) bool, the triangles whose material responds to light. What
    does not depend on the light (receivers, convexity, the knots' vertices) is found once."""
    if not rows or not knots or len(tri_vertices) == 0:
        return set()
    still = [j for j in rows if all(np.array_equal(k.lights[j], knots[0].lights[j]) for k in knots[1:])]
    if not still:
        return set()
    visible = np.zeros(len(tri_vertices), bool)
    for k in knots:
        visible |= k.tri_visible if len(k.tri_visible) else True
    lit = visible & tri_receives
    if not lit.any():
        return set(still)
    if not may_drop_lights(visible, tri_receives, tri_self_safe):   # an open or smooth receiver (a ground)
        return set()
    receivers = np.unique(tri_object[lit])
    objects = np.unique(tri_object[visible])
    if len(objects) > MAX_OBJECTS:
        return set()
    # each visible vertex at every knot, once; each triangle corner's vertex, and its object
    tris = tri_vertices[visible]
    used = np.unique(tris)
    stacked = np.stack([k.positions[used] for k in knots])   # (K + 1, U, 3)
    for o in receivers:   # convex at every knot (a deforming mesh may fold between them)
        mine = tri_object == o
        faces = tri_vertices[mine & visible]   # (its faces seen at no knot neither cast nor receive)
        if not tri_self_safe[mine].all() or len(faces) * len(np.unique(faces)) * len(knots) > MAX_CONVEX_WORK:
            return set()
        if not is_convex_solid(stacked, np.searchsorted(used, faces)):
            return set()
    if len(objects) == 1:
        return set(still)
    corner = np.searchsorted(used, tris.ravel())
    owner = np.searchsorted(objects, np.repeat(tri_object[visible], 3))
    is_receiver = np.isin(objects, receivers)

    def extents(dirs: np.ndarray):
        """(lo, hi) (O, D) of each object along dirs (D, 3) over the knots, or None if not finite."""
        v_lo = np.full((len(used), len(dirs)), np.inf)
        v_hi = np.full((len(used), len(dirs)), -np.inf)
        step = max(1, EXTENT_CHUNK // max(len(used) * len(dirs), 1))   # knots a pass: bounded memory
        with np.errstate(over="ignore", invalid="ignore"):   # (huge coordinates: not finite, checked below)
            for k0 in range(0, len(stacked), step):
                proj = stacked[k0:k0 + step] @ dirs.T   # (<= step, U, D); NaN carries through
                v_lo, v_hi = np.minimum(v_lo, proj.min(axis=0)), np.maximum(v_hi, proj.max(axis=0))
        lo = np.full((len(objects), len(dirs)), np.inf)
        hi = np.full((len(objects), len(dirs)), -np.inf)
        np.minimum.at(lo, owner, v_lo[corner])
        np.maximum.at(hi, owner, v_hi[corner])
        return (lo, hi) if np.isfinite(lo).all() and np.isfinite(hi).all() else None

    local = [j for j in still if int(knots[0].lights[j][0]) != DISTANT]
    solid = extents(SOLID_DIRECTIONS) if local else None   # shared by the local lights
    out = set()
    for j in still:
        row = knots[0].lights[j]
        if int(row[0]) == DISTANT:   # outlines across the beam
            _origin, axes = light_frame(row)
            angles = np.pi * np.arange(DIRECTIONS) / DIRECTIONS
            dirs = np.cos(angles)[:, None] * axes[0] + np.sin(angles)[:, None] * axes[1]   # (D, 3)
            ext = extents(dirs)
        else:   # extents in space, beside the light's
            dirs = SOLID_DIRECTIONS
            ext = solid
        if ext is None:
            continue
        lo, hi = ext
        # where a receiver's shadows can come from: across a distant light's beam, its own outline;
        # from a local light, the hull of it and the light (a ball of the light's reach around its
        # position holds every sample point of its maps), which a caster must meet along every direction
        reach_lo, reach_hi = lo, hi
        if int(row[0]) != DISTANT:
            centre = np.asarray(row[4:7], np.float64) @ dirs.T
            reach = light_reach(row)
            reach_lo, reach_hi = np.minimum(lo, centre - reach), np.maximum(hi, centre + reach)
        meet = ((lo[:, None, :] <= reach_hi[None, :, :]) & (reach_lo[None, :, :] <= hi[:, None, :])).all(axis=2)
        np.fill_diagonal(meet, False)   # (caster, receiver): itself is the convexity test's
        if not meet[:, is_receiver].any():
            out.add(j)
    return out


def light_reach(row: np.ndarray) -> float:
    """Radius around a local light's position within which all its shadow maps' sample points lie
    (layout.light_sample_offsets): a sphere light's radius, a disk's, a rect's half-diagonal."""
    kind = int(row[0])
    u, v = float(np.linalg.norm(row[10:13])), float(np.linalg.norm(row[13:16]))
    if kind == RECT:
        return float(np.hypot(u, v))
    if kind == DISK:
        return u
    return max(float(row[16]), 0.0)

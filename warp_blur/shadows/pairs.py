"""Lights whose shadows can fall on nothing lit: no maps are made for them.

A shadow changes a pixel only where a caster comes between a light and a lit receiver. Looking along
a distant light, a caster can shadow a receiver only where their outlines across the beam overlap;
each object's outline is bounded by its extents along DIRECTIONS in the plane across the beam (a 2D
k-DOP), taken over every knot of the frame's motion plan: the maps see the scene only between
consecutive knots, linearly, and the knots' extents hold every such point. An object shadows itself
only where it is not a convex solid: the faces of a closed, convex, flat-shaded solid turned away
from the light are unlit by their own normal, and those are exactly the faces its maps would darken
(a smooth-shaded or normal-mapped one may light them through its shading normals, so it keeps its
maps); it must be convex at every knot. Emissive-only surfaces receive nothing. The test is
conservative: a light is dropped only when no (caster, receiver) pair can meet; local lights
(sphere, disk, rect) and lights that move, switch or change over the shutter keep their maps.
"""

from __future__ import annotations

import numpy as np

from ..usd.lights import DISTANT
from ..usd.materials import COL_NORMAL_BINDING
from ..usd.units import FLAG_SMOOTH
from .layout import Sample, light_frame

#: tests switch this off to compare against building every shadowing light's maps
PAIR_CULLING = True
#: directions across a distant light's beam along which outlines are compared
DIRECTIONS = 8
#: objects beyond this many are not compared pair by pair (their maps are kept)
MAX_OBJECTS = 256
#: an object is checked for convexity only up to this many (faces × vertices, over all knots:
#: a larger flat closed mesh keeps its maps)
MAX_CONVEX_WORK = 4_000_000
#: a vertex this far (relative to the object's size) outside a face's plane makes it non-convex
CONVEX_TOL = 1e-6


def responds_to_light(material_table: np.ndarray) -> np.ndarray:
    """(M,) bool: materials whose surfaces reflect light (vertex colours, textures, a diffuse or
    specular colour): what a shadow can darken."""
    m = material_table
    return (m[:, 10] > 0.5) | (m[:, 21] > 0.5) | (np.abs(m[:, 0:3]).sum(axis=1) > 0) | (np.abs(m[:, 6:9]).sum(axis=1) > 0)


def is_convex_solid(positions: np.ndarray, tris: np.ndarray) -> bool:
    """True when every vertex of triangles tris ((F, 3) indices into positions (V, 3)) lies on one
    side of each of their planes (within CONVEX_TOL of the size): a closed such surface bounds a
    convex solid. Too large a mesh to check (MAX_CONVEX_WORK), or one with no finite size, counts
    as not convex."""
    verts = np.unique(tris)
    if len(tris) == 0 or len(tris) * len(verts) > MAX_CONVEX_WORK:
        return False
    p = positions[verts]
    with np.errstate(over="ignore", invalid="ignore"):
        centre = 0.5 * (p.min(axis=0) + p.max(axis=0))
        size = float(np.max(p.max(axis=0) - p.min(axis=0)))
    if not np.isfinite(size) or size <= 0.0 or not np.isfinite(centre).all():
        return False
    q = (positions - centre) / size   # the object's own scale: no overflow, one tolerance
    a, b, c = q[tris[:, 0]], q[tris[:, 1]], q[tris[:, 2]]
    n = np.cross(b - a, c - a)
    lengths = np.linalg.norm(n, axis=1)
    use = lengths > 1e-12
    if not use.any():
        return False
    side = np.einsum("fvk,fk->fv", q[verts][None, :, :] - a[use, None, :], n[use])   # (F, n) signed, × |normal|
    tol = (CONVEX_TOL * lengths[use])[:, None]
    return bool(((side <= tol).all(axis=1) | (side >= -tol).all(axis=1)).all())


def pair_receivers(scene) -> tuple[np.ndarray, np.ndarray] | None:
    """(tri_receives, tri_self_safe) of a usd.scene.Scene, (T,) bool each: the triangles whose
    material responds to light, and those of closed, opaque, flat-shaded prims without a normal
    map (a convex one cannot shadow itself on a lit face); None when PAIR_CULLING is off."""
    if not PAIR_CULLING:
        return None
    receives = responds_to_light(scene.material_table)[scene.tri_material]
    normal_mapped = (scene.material_table[:, COL_NORMAL_BINDING] >= 0)[scene.tri_material]
    return receives, scene.tri_closed & ((scene.tri_flags & FLAG_SMOOTH) == 0) & ~normal_mapped


def light_shadows_nothing(j: int, knots: list[Sample], tri_vertices: np.ndarray, tri_object: np.ndarray,
                          tri_receives: np.ndarray, tri_self_safe: np.ndarray) -> bool:
    """True when light row j can darken no lit surface of the scene given at the plan's knots:
    no receiving object's outline across the beam meets another object's, and each receiving
    object is a convex solid (tri_self_safe: closed, opaque and flat-shaded; checked convex here).
    tri_receives: (T,) bool, the triangles whose material responds to light."""
    if not knots or len(tri_vertices) == 0:
        return False
    row = knots[0].lights[j]
    if int(row[0]) != DISTANT or any(not np.array_equal(k.lights[j], row) for k in knots[1:]):
        return False
    visible = np.zeros(len(tri_vertices), bool)
    for k in knots:
        visible |= k.tri_visible if len(k.tri_visible) else True
    lit = visible & tri_receives
    if not lit.any():
        return True
    if (lit & ~tri_self_safe).any():   # an open or smooth receiver (the usual ground): no further look
        return False
    receivers = np.unique(tri_object[lit])
    objects = np.unique(tri_object[visible])
    if len(objects) > MAX_OBJECTS:
        return False
    for o in receivers:   # convex at every knot (a deforming mesh may fold between them)
        mine = tri_object == o
        faces = tri_vertices[mine]
        if not tri_self_safe[mine].all() or len(faces) * len(np.unique(faces)) * len(knots) > MAX_CONVEX_WORK:
            return False
        if not all(is_convex_solid(k.positions, faces) for k in knots):
            return False
    if len(objects) == 1:
        return True
    _origin, axes = light_frame(row)
    angles = np.pi * np.arange(DIRECTIONS) / DIRECTIONS
    across = np.cos(angles)[:, None] * axes[0] + np.sin(angles)[:, None] * axes[1]   # (D, 3)
    # each visible vertex's extents over the knots, then each object's over its vertices
    tris = tri_vertices[visible]
    used = np.unique(tris)
    with np.errstate(over="ignore", invalid="ignore"):   # (huge coordinates: not finite, checked below)
        proj = np.stack([k.positions[used] for k in knots]) @ across.T   # (K + 1, U, D)
        v_lo, v_hi = proj.min(axis=0), proj.max(axis=0)
    corner = np.searchsorted(used, tris.ravel())   # each triangle corner's vertex, and its object
    owner = np.searchsorted(objects, np.repeat(tri_object[visible], 3))
    lo = np.full((len(objects), DIRECTIONS), np.inf)
    hi = np.full((len(objects), DIRECTIONS), -np.inf)
    np.minimum.at(lo, owner, v_lo[corner])
    np.maximum.at(hi, owner, v_hi[corner])
    if not (np.isfinite(lo).all() and np.isfinite(hi).all()):
        return False
    recv = np.isin(objects, receivers)
    meet = ((lo[:, None, :] <= hi[None, :, :]) & (lo[None, :, :] <= hi[:, None, :])).all(axis=2)   # (O, O)
    np.fill_diagonal(meet, False)
    return not meet[recv].any()

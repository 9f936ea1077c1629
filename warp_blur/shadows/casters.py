"""Triangles that cannot shadow anything from a light, left out of its maps.

A triangle whose plane has the light strictly on one side and every vertex of the scene on that
side or on the plane cannot come between the light and any point of the scene: the segment from
the light to a receiver never crosses the plane. A floor under everything lit from above, or the
walls of a room seen from a lamp inside it, only ever "shadows" itself, which the maps' bias is
there to undo. Leaving such triangles out changes no exact visibility and saves their texels in
every map (a moving lamp otherwise re-renders the floor at every instant).

Candidates come from one sample (the shutter centre): a triangle's plane must have the scene's
extreme vertices in 26 directions on one side, and the planes that pass are checked exactly against
every vertex. Each kept plane is then checked again at every probe instant, with the light's
sample positions (or its direction, for a distant light) at that instant.
"""

from __future__ import annotations

from typing import Callable

import numpy as np

from ..raster.triangle_sizes import triangles_at_least
from ..usd.lights import DISTANT
from .layout import LightLayout, Sample, light_frame
from .vertex_passes import DIRECTIONS, support

#: most planes checked exactly per frame (the largest first); triangles of the others stay in the maps
MAX_PLANES = 32
#: a vertex within this distance (relative to the scene's extent) of a plane lies on it
PLANE_TOL = 1e-6
#: triangles smaller than (extent / MIN_SIDE)² are not considered: they cover a few texels of a
#: map at most, and skipping them keeps the search to a few ms on 70k-triangle scenes
MIN_SIDE = 256.0


class PlaneGroup:
    """Visible triangles (indices) lying in one plane at the centre sample, with every vertex of
    the scene on one side of it or on it there."""

    def __init__(self, tris: np.ndarray, representative: int) -> None:
        self.tris = tris
        self.representative = representative   # the group's largest triangle: its plane at any instant


def used_vertex_index(tri_visible: np.ndarray, tri_vertices: np.ndarray, num_points: int) -> np.ndarray:
    """(U,) ascending indices of the vertices of the triangles tri_visible (a (T,) mask; empty:
    none) marks, out of num_points."""
    mask = np.zeros(num_points, bool)
    if len(tri_visible):
        mask[tri_vertices[tri_visible].ravel()] = True
    return np.flatnonzero(mask)


def used_vertices(s: Sample, tri_vertices: np.ndarray) -> np.ndarray:
    """(U, 3) positions at sample s of the vertices of visible triangles (the scene that can
    cast or receive a shadow)."""
    return s.positions[used_vertex_index(s.tri_visible, tri_vertices, len(s.positions))]


def _cross(u: np.ndarray, v: np.ndarray) -> np.ndarray:
    """Row-wise u × v of (N, 3) arrays (np.cross is several times slower on long arrays)."""
    return np.stack([u[:, 1] * v[:, 2] - u[:, 2] * v[:, 1], u[:, 2] * v[:, 0] - u[:, 0] * v[:, 2],
                     u[:, 0] * v[:, 1] - u[:, 1] * v[:, 0]], axis=1)


def bounding_planes(s: Sample, tri_vertices: np.ndarray) -> list[PlaneGroup]:
    """Groups of coplanar visible triangles at sample s whose plane has the whole scene (the
    vertices of visible triangles) on one side: at most MAX_PLANES, the largest area first."""
    visible = np.nonzero(s.tri_visible)[0] if len(s.tri_visible) else np.zeros(0, np.int64)
    if len(visible) == 0:
        return []
    used = used_vertices(s, tri_vertices)
    hi, extreme_at = support(used)
    extent = float(max(hi[i] + hi[j] for i, j in _OPPOSITE_AXES)) + 1e-30
    tol = PLANE_TOL * extent
    with np.errstate(over="ignore"):   # a scene of extent ~1e300 (hostile input): no plane then
        min_area2 = 2.0 * np.square(extent / MIN_SIDE)
    # the kernel drops the small triangles first (half the bound: its rounding may differ from
    # NumPy's), so the passes below gather only the few that can hold a bounding plane
    visible = triangles_at_least(s.positions, tri_vertices, visible, 0.5 * min_area2)
    if len(visible) == 0:
        return []
    tv = tri_vertices[visible]
    p = s.positions
    a = p[tv[:, 0]]
    n = _cross(p[tv[:, 1]] - a, p[tv[:, 2]] - a)
    area2 = np.sqrt(np.einsum("ij,ij->i", n, n))
    ok = np.nonzero(area2 >= min_area2)[0]
    # the extreme vertices along the axes first (most planes fail there), then the diagonals
    for rows in (_AXES, ~_AXES):
        if len(ok) == 0:
            return []
        extreme = used[np.unique(extreme_at[rows])]
        nk = n[ok] / area2[ok, None]
        dist = extreme @ nk.T - np.einsum("ij,ij->i", nk, a[ok])      # (X, T)
        ok = ok[(dist >= -tol).all(axis=0) | (dist <= tol).all(axis=0)]
    if len(ok) == 0:
        return []
    tris, area2 = visible[ok], area2[ok]
    n = n[ok] / area2[:, None]
    d = np.einsum("ij,ij->i", n, a[ok])
    # one orientation per plane (a floor's triangles may be wound either way), then group
    flip = np.where(n[np.arange(len(n)), np.abs(n).argmax(axis=1)] < 0, -1.0, 1.0)
    key = np.concatenate([np.round(n * flip[:, None] / PLANE_TOL), np.round(d * flip / tol)[:, None]], axis=1)
    group = np.unique(key, axis=0, return_inverse=True)[1].ravel()
    areas = np.bincount(group, weights=area2)
    order = np.argsort(-areas)[:MAX_PLANES]
    members = [np.nonzero(group == g)[0] for g in order]
    reps = np.array([m[np.argmax(area2[m])] for m in members])
    # every vertex against every plane, in chunks: a plane that fails is dropped at the first chunk
    pos = np.ones(len(reps), bool)
    neg = np.ones(len(reps), bool)
    for start in range(0, len(used), 8192):
        alive = np.nonzero(pos | neg)[0]
        if len(alive) == 0:
            break
        side = used[start:start + 8192] @ n[reps[alive]].T - d[reps[alive]]
        pos[alive] &= (side >= -tol).all(axis=0)
        neg[alive] &= (side <= tol).all(axis=0)
    return [PlaneGroup(tris[m], int(tris[r])) for m, r, h in zip(members, reps, pos | neg) if h]


_AXES = np.abs(DIRECTIONS).sum(axis=1) == 1
_OPPOSITE_AXES = [(int(np.nonzero((DIRECTIONS == e).all(axis=1))[0][0]),
                   int(np.nonzero((DIRECTIONS == -e).all(axis=1))[0][0])) for e in np.eye(3)]


def light_positions(lay: LightLayout, s: Sample) -> tuple[np.ndarray, bool]:
    """(eye points (M, 3) of the light's samples, or its direction towards the light (1, 3) for a
    distant light; True when distant) in camera space at sample s."""
    origin, axes = light_frame(s.lights[lay.row])
    if lay.kind == DISTANT:
        return (lay.faces[0].rotation @ axes)[2:3], True
    return origin + lay.offsets @ axes, False


def probe_scene(s: Sample, tri_vertices: np.ndarray) -> tuple[np.ndarray, float]:
    """(used vertices (U, 3), on-plane tolerance) of the scene at probe s: what every light's
    check at that probe reads."""
    used = used_vertices(s, tri_vertices)
    return used, PLANE_TOL * (float(np.ptp(used, axis=0).max(initial=0.0)) + 1e-30)


def non_casters(groups: list[PlaneGroup], lay: LightLayout, probes: list[Sample],
                tri_vertices: np.ndarray, scenes: dict | None = None) -> np.ndarray:
    """(T,) bool: triangles of the groups that cannot shadow anything from light lay at any probe
    (their plane, taken at each probe, has the light strictly on the side all the scene is on).
    scenes: (sample, *probe_scene) by id of the probe's sample, shared by the frame's lights."""
    out = np.zeros(len(tri_vertices), bool)
    alive = list(groups)
    scenes = {} if scenes is None else scenes
    for s in probes:
        if not alive:
            break
        if id(s) not in scenes:   # the sample is kept with its entry, so its id is not reused
            scenes[id(s)] = (s, *probe_scene(s, tri_vertices))
        _s, used, tol = scenes[id(s)]
        eyes, distant = light_positions(lay, s)
        alive = [g for g in alive if _plane_holds(g, s, used, tol, eyes, distant, tri_vertices)]
    for g in alive:
        out[g.tris] = True
    return out


def _plane_holds(g: PlaneGroup, s: Sample, used: np.ndarray, tol: float, eyes: np.ndarray, distant: bool,
                 tri_vertices: np.ndarray) -> bool:
    """True when at sample s the group's triangles still lie in one plane with every used vertex
    on one side of it and the light (eye points, or its direction when distant) strictly on that
    side."""
    if len(s.tri_visible) and not s.tri_visible[g.tris].all():
        return False
    a, b, c = s.positions[tri_vertices[g.representative]]
    n = np.cross(b - a, c - a)
    length = float(np.linalg.norm(n))
    if length <= (tol * 1e-3) ** 2:
        return False
    n = n / length
    d = float(n @ a)
    if np.abs(s.positions[tri_vertices[g.tris].ravel()] @ n - d).max() > tol:
        return False
    side = used @ n - d
    sign = 1.0 if (side >= -tol).all() else -1.0 if (side <= tol).all() else 0.0
    if sign == 0.0:
        return False
    if distant:
        return bool((sign * (eyes @ n) > 1e-9).all())
    return bool((sign * (eyes @ n - d) > tol).all())


def light_casters(layouts: list[LightLayout], centre: Sample, probes: Callable[[LightLayout], list[Sample]],
                  tri_vertices: np.ndarray) -> tuple[dict[int, np.ndarray | None], list[int]]:
    """Per light row, the (T,) triangles that may cast a shadow (None: all), and per light how many
    cannot. A light's planes are checked at its probes(lay): the still-triangle probes when
    anything moves in its view, the centre alone when nothing does."""
    groups = bounding_planes(centre, tri_vertices)
    casters: dict[int, np.ndarray | None] = {}
    dropped = []
    scenes: dict = {}   # each probe's used vertices and tolerance, computed once for all lights
    for lay in layouts:
        out = non_casters(groups, lay, probes(lay), tri_vertices, scenes) if groups else None
        casters[lay.row] = ~out if out is not None and out.any() else None
        dropped.append(int(out.sum()) if out is not None else 0)
    return casters, dropped

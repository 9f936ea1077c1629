"""Triangles for USD geometry: polygon meshes fan-triangulated, implicit gprims tessellated (trimesh)."""

from __future__ import annotations

import functools

import numpy as np
from pxr import Usd, UsdGeom

from ..core.log import warn_once
from ..core.settings import DEFAULT_SPHERE_ERROR_PX
from .shape_cache import cached_arrays


def triangulate_corners(counts: np.ndarray, indices: np.ndarray, holes: np.ndarray | None = None,
                        left_handed: bool = False) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Fan-triangulate polygons. Returns (tris (T,3) int32, face index of each triangle (T,),
    face-vertex position of each triangle corner (T,3) int64, for faceVarying primvars).

    Faces with fewer than 3 vertices and hole faces are skipped; leftHanded winding is flipped so
    that every triangle winds counter-clockwise around its front-face normal.
    """
    counts = np.asarray(counts, np.int64)
    indices = np.asarray(indices, np.int64)
    starts = np.concatenate([[0], np.cumsum(counts)[:-1]]) if len(counts) else np.zeros(0, np.int64)
    keep = counts >= 3
    if holes is not None and len(holes):
        hole_mask = np.zeros(len(counts), bool)
        valid = (holes >= 0) & (holes < len(counts))
        hole_mask[np.asarray(holes)[valid]] = True
        keep &= ~hole_mask
    faces = np.nonzero(keep)[0]
    n_tri = counts[faces] - 2
    face_of_tri = np.repeat(faces, n_tri)
    # corner k of the fan within its face: 1 .. count-2
    first_tri = np.concatenate([[0], np.cumsum(n_tri)[:-1]]) if len(n_tri) else np.zeros(0, np.int64)
    k = np.arange(len(face_of_tri)) - np.repeat(first_tri, n_tri) + 1
    s = starts[face_of_tri]
    corners = np.stack([s, s + k, s + k + 1], axis=1)
    if left_handed:
        corners = corners[:, [0, 2, 1]]
    return indices[corners].astype(np.int32), face_of_tri, corners


#: USD's cube (UsdImaging / GeomUtil's cuboid): points of a unit cube and its six quads in the
#: order per-face (uniform) primvars follow: +Z, -Z, +Y, -Y, +X, -X.
CUBE_POINTS = np.array([(0.5, 0.5, 0.5), (-0.5, 0.5, 0.5), (-0.5, -0.5, 0.5), (0.5, -0.5, 0.5),
                        (-0.5, -0.5, -0.5), (-0.5, 0.5, -0.5), (0.5, 0.5, -0.5), (0.5, -0.5, -0.5)], np.float64)
CUBE_INDICES = np.array([0, 1, 2, 3, 4, 5, 6, 7, 0, 6, 5, 1, 4, 7, 3, 2, 0, 3, 7, 6, 4, 2, 1, 5], np.int64)


@functools.lru_cache(maxsize=4)
def _axis_rotation(axis: str) -> np.ndarray:
    """4x4 (column-vector) rotation taking trimesh's +Z axis to USD's `axis` (trimesh's own
    matrix, kept on disk: shape_cache.py). Read-only: shared by every caller."""
    rot = np.eye(4)
    if axis in ("X", "Y"):
        rot = np.array(cached_arrays(f"axis rotation {axis}", lambda: (_trimesh_axis_rotation(axis),))[0])
    rot.flags.writeable = False
    return rot


def _trimesh_axis_rotation(axis: str) -> np.ndarray:
    """trimesh's rotation taking +Z to `axis` ("X" or "Y")."""
    import trimesh   # imported where used: it costs ~0.6 s at start-up (shape_cache.py)
    if axis == "X":
        return trimesh.transformations.rotation_matrix(np.pi / 2, [0, 1, 0])
    return trimesh.transformations.rotation_matrix(-np.pi / 2, [1, 0, 0])


#: icosphere subdivisions of an implicit sphere that is large on screen (1280 triangles)
SPHERE_LEVEL_MAX = 3
#: how far (pixels) a sphere's facets may fall inside its true surface on screen by default
#: (RenderSettings.sphere_error_px and its presets): spheres small on screen take the fewest
#: subdivisions that keep to it (sphere_levels)
SPHERE_SAG_PX = DEFAULT_SPHERE_ERROR_PX
#: the deepest a unit-radius icosphere's facets fall inside the sphere, per subdivision level
#: (trimesh's icospheres: tests/test_tessellate.py measures them)
ICOSPHERE_SAG = (0.20535, 0.065828, 0.017753, 0.0045284)


def sphere_levels(radius_px: np.ndarray, error_px: float | None = None) -> np.ndarray:
    """(N,) int icosphere subdivisions (0 .. SPHERE_LEVEL_MAX) for spheres whose radii on screen
    are radius_px (N,) pixels (inf: unknown or at the eye): the fewest whose facets fall at most
    error_px (None: SPHERE_SAG_PX) inside the silhouette, and never more than SPHERE_LEVEL_MAX
    (the level every sphere had before: large spheres are tessellated as they were)."""
    bound = SPHERE_SAG_PX if error_px is None else float(error_px)
    r = np.asarray(radius_px, np.float64)
    level = np.full(r.shape, SPHERE_LEVEL_MAX, np.int64)
    for s in range(SPHERE_LEVEL_MAX - 1, -1, -1):
        level[ICOSPHERE_SAG[s] * r <= bound] = s
    return level


def sphere_radius_px(proj, local_to_cam: np.ndarray, radius: float) -> np.ndarray:
    """(N,) radii in pixels on screen of a sphere of `radius` (its local units) placed by
    local_to_cam (N, 4, 4) row-vector matrices under projection proj (core.camera.Projection): the
    radius scaled by the matrices' largest stretch, over the depth of the sphere's nearest point,
    and widened by how far off the view axis it sits (a sphere off axis projects to an ellipse
    longer across it). inf where the sphere reaches the near plane or behind the eye."""
    m = np.asarray(local_to_cam, np.float64).reshape(-1, 4, 4)
    finite = np.isfinite(m).all(axis=(1, 2))
    stretch = np.full(len(m), np.inf)
    if finite.any():   # (LAPACK's SVD fails on NaN and complains of inf)
        stretch[finite] = np.linalg.norm(m[finite, :3, :3], ord=2, axis=(1, 2))
    x0, y0, x1, y1 = proj.window
    with np.errstate(all="ignore"):
        r = abs(float(radius)) * stretch
        centre = m[:, 3, :3]
        px_per_unit = max(proj.width / abs(x1 - x0), proj.height / abs(y1 - y0))
        if proj.orthographic:
            out = r * px_per_unit
        else:
            depth = -centre[:, 2]
            near = depth - r
            off_axis = np.sqrt(1.0 + (centre[:, 0] / depth) ** 2 + (centre[:, 1] / depth) ** 2)   # |c| / depth
            out = r * px_per_unit / near * off_axis
            out[~(near > max(proj.near, 0.0))] = np.inf
    out[~np.isfinite(out)] = np.inf
    return out


def tessellate_gprim(prim: Usd.Prim, time: Usd.TimeCode, sphere_level: int = SPHERE_LEVEL_MAX) -> tuple | None:
    """(points (N,3) float64, tris (T,3) int32, smooth, face of each triangle (T,), face-vertex
    position of each corner (T,3) or None) for an implicit gprim, or None if unknown. The cube
    has USD's own faces (primvars of every interpolation apply); the other shapes' faces are
    their triangles. A sphere is an icosphere of `sphere_level` subdivisions (sphere_levels)."""
    out = _tessellate(prim, time, sphere_level)
    if out is None:
        return None
    pts, tris, smooth = out
    if prim.IsA(UsdGeom.Cube):
        _, face_of_tri, corners = _cube_topology()   # tris is the same table
        return pts, tris, smooth, face_of_tri, corners
    return pts, tris, smooth, np.arange(len(tris)), None


@functools.lru_cache(maxsize=1)
def _cube_topology() -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """(triangles (12, 3), face of each (12,), face-vertex position of each corner (12, 3)) of
    USD's cube, triangulated once for every cube (read-only)."""
    out = triangulate_corners(np.full(6, 4), CUBE_INDICES)
    for a in out:
        a.flags.writeable = False
    return out


def gprim_number(attr: Usd.Attribute, time: Usd.TimeCode) -> float:
    """A gprim's dimension at `time`. A value that is no real number (an attribute authored with a
    type USD does not know, such as `xdouble size`, reads as an unregistered value) gives the
    schema's fallback, with a warning once per attribute."""
    value = attr.Get(time)
    try:
        return float(value)
    except (TypeError, ValueError):
        prim = attr.GetPrim()
        definition = Usd.SchemaRegistry().FindConcretePrimDefinition(prim.GetTypeName())
        fallback = definition.GetAttributeFallbackValue(attr.GetName()) if definition else None
        fallback = 1.0 if fallback is None else float(fallback)
        warn_once(f"not-a-number:{attr.GetPath()}",
                  f"{attr.GetPath()}: {type(value).__name__} is not a number; using {fallback:g}")
        return fallback


def _tessellate(prim: Usd.Prim, time: Usd.TimeCode, sphere_level: int) -> tuple[np.ndarray, np.ndarray, bool] | None:
    """(points (N, 3) float64, triangles (T, 3) int32, smooth) of an implicit gprim at `time`;
    shapes of the same kind and dimensions share one read-only pair (_trimesh_shape)."""
    if prim.IsA(UsdGeom.Cube):   # USD's own topology, so per-face and per-vertex primvars line up
        size = gprim_number(UsdGeom.Cube(prim).GetSizeAttr(), time)
        return CUBE_POINTS * size, _cube_topology()[0], False
    if prim.IsA(UsdGeom.Plane):
        g = UsdGeom.Plane(prim)
        w, ln = gprim_number(g.GetWidthAttr(), time) / 2, gprim_number(g.GetLengthAttr(), time) / 2
        pts = np.array([[-w, -ln, 0], [w, -ln, 0], [w, ln, 0], [-w, ln, 0]], np.float64)
        tris = np.array([[0, 1, 2], [0, 2, 3]], np.int32)
        pts = (pts @ _axis_rotation(g.GetAxisAttr().Get(time))[:3, :3].T)
        return pts, tris, False
    for schema, kind in ((UsdGeom.Sphere, "sphere"), (UsdGeom.Cylinder, "cylinder"), (UsdGeom.Cone, "cone"),
                         (UsdGeom.Capsule, "capsule")):
        if prim.IsA(schema):
            g = schema(prim)
            radius = gprim_number(g.GetRadiusAttr(), time)
            height = 0.0 if kind == "sphere" else gprim_number(g.GetHeightAttr(), time)
            axis = "Z" if kind == "sphere" else str(g.GetAxisAttr().Get(time))
            pts, tris = _trimesh_shape(kind, radius, height, axis, int(sphere_level) if kind == "sphere" else 0)
            return pts, tris, kind in ("sphere", "capsule")
    return None


@functools.lru_cache(maxsize=1024)
def _trimesh_shape(kind: str, radius: float, height: float, axis: str, level: int = SPHERE_LEVEL_MAX
                   ) -> tuple[np.ndarray, np.ndarray]:
    """(points, triangles) of a sphere (an icosphere of `level` subdivisions; below
    SPHERE_LEVEL_MAX scaled to the full level's surface area), cylinder, cone or capsule, made by
    trimesh (~0.2-0.5 ms each) once per kind and dimensions and kept on disk for later processes
    (shape_cache.py): a stage of a thousand proxy spheres makes one. Read-only: every prim of
    those dimensions shares them."""
    key = f"{kind} radius {radius!r} height {height!r} axis {axis} level {level}"
    pts, tris = cached_arrays(key, lambda: _make_trimesh_shape(kind, radius, height, axis, level))
    pts, tris = np.array(pts, np.float64), np.array(tris, np.int32)
    pts.flags.writeable = False
    tris.flags.writeable = False
    return pts, tris


def _make_trimesh_shape(kind: str, radius: float, height: float, axis: str, level: int
                        ) -> tuple[np.ndarray, np.ndarray]:
    """_trimesh_shape's arrays, made by trimesh."""
    import trimesh   # imported where used: it costs ~0.6 s at start-up (shape_cache.py)

    if kind == "sphere":
        mesh = trimesh.creation.icosphere(subdivisions=level, radius=radius)
        if level < SPHERE_LEVEL_MAX:
            # as much area seen on average as the full level's (a convex body's mean silhouette is
            # a quarter of its surface): a field of small spheres keeps its coverage
            full = trimesh.creation.icosphere(subdivisions=SPHERE_LEVEL_MAX, radius=1.0).area
            mesh.apply_scale(float(np.sqrt(full / trimesh.creation.icosphere(subdivisions=level, radius=1.0).area)))
    elif kind == "cylinder":
        mesh = trimesh.creation.cylinder(radius=radius, height=height, sections=32)
        mesh.apply_transform(_axis_rotation(axis))
    elif kind == "cone":
        mesh = trimesh.creation.cone(radius=radius, height=height, sections=32)
        mesh.apply_translation((0, 0, -height / 2))
        mesh.apply_transform(_axis_rotation(axis))
    else:
        mesh = trimesh.creation.capsule(height=height, radius=radius, count=[16, 16])
        mesh.apply_translation(-mesh.bounds.mean(axis=0))
        mesh.apply_transform(_axis_rotation(axis))
    return np.array(mesh.vertices, np.float64), np.array(mesh.faces, np.int32)


#: is_closed_surface tests surfaces of at most this many triangles in plain Python
SMALL_SURFACE_TRIANGLES = 64


def is_closed_surface(tris: np.ndarray, points: np.ndarray) -> bool:
    """True when triangles (T, 3) over points (N, 3) form closed, consistently oriented surfaces
    (points at the same position welded: seams of split normals or texture coordinates): every
    directed edge a -> b appears once and its reverse b -> a once. A ray from outside such a
    surface enters it through a front face first, so its back faces cannot show."""
    if len(tris) == 0 or len(points) == 0:
        return False
    if len(tris) <= SMALL_SURFACE_TRIANGLES:
        return _small_surface_closed(np.asarray(tris).tolist(), np.asarray(points, np.float64).tolist())
    tris = np.asarray(tris, np.int64)
    if _edges_pair_up(tris, len(points)):
        return True
    rows = np.ascontiguousarray(np.asarray(points, np.float64) + 0.0)     # + 0.0: -0.0 and 0.0 alike
    _, weld = np.unique(rows.view(np.dtype((np.void, rows.itemsize * 3))).ravel(), return_inverse=True)
    return _edges_pair_up(weld.reshape(-1)[tris], len(points))


def _small_surface_closed(tris: list, points: list) -> bool:
    """is_closed_surface for a few triangles, in plain Python (NumPy's calls cost more than the
    work): the same test, points welded by equal coordinates."""
    if _edge_set_pairs_up(tris):
        return True
    weld: dict[tuple, int] = {}
    ids = [weld.setdefault(tuple(p), len(weld)) for p in points]   # -0.0 == 0.0 as keys, as + 0.0 makes them
    return _edge_set_pairs_up([[ids[v] for v in t] for t in tris])


def _edge_set_pairs_up(tris: list) -> bool:
    """_edges_pair_up for a list of triangles: no repeated or degenerate directed edge, and each
    one's reverse present."""
    edges = set()
    for t in tris:
        for a, b in ((t[0], t[1]), (t[1], t[2]), (t[2], t[0])):
            if a == b or (a, b) in edges:
                return False
            edges.add((a, b))
    return all((b, a) in edges for a, b in edges)


def _edges_pair_up(tris: np.ndarray, n: int) -> bool:
    """Every directed edge of triangles (T, 3) over n points appears once, and its reverse once."""
    a, b = tris.ravel(), np.roll(tris, -1, axis=1).ravel()
    if (a == b).any():
        return False
    forward, backward = np.sort(a * n + b), np.sort(b * n + a)
    return bool((np.diff(forward) != 0).all() and np.array_equal(forward, backward))

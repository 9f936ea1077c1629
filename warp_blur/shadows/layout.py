"""Shadow-map layout: options, the faces and samples of each light, and the frame's map data
(what shadows/maps.py renders into and the kernels read): lights' frames, area-light sample
patterns, cube faces and fitted frusta."""

from __future__ import annotations

import functools
from dataclasses import dataclass, field
from typing import TYPE_CHECKING

import numpy as np

from ..core.camera import Projection
from ..usd.lights import DISK, DISTANT, RECT, SPHERE

if TYPE_CHECKING:
    from .texel_major import TexelMajorLayout

FAR = 1.0e30
#: a single fitted frustum is used when all geometry is within this angle of one direction
MAX_FRUSTUM_HALF_ANGLE_COS = 0.5


@dataclass(frozen=True)
class ShadowOptions:
    """mode: auto | warped | direct | off (auto: per light, warped only where it is measured
    cheaper than direct maps for this frame); size: texels per face side; grid: control-point cells per side;
    times: map instants over the shutter for the time-continuous methods; keys: most key maps per
    light (warped); light_samples: samples of an area light; bias, normal_bias: texels; pcf:
    filter radius in texels; memory_mb: budget of one frame's maps."""

    mode: str = "warped"
    size: int = 512
    grid: int = 128
    times: int = 8
    keys: int = 5
    light_samples: int = 1
    bias: float = 1.0
    normal_bias: float = 1.5
    pcf: int = 0
    memory_mb: float = 1024.0


@dataclass
class Sample:
    """The scene at one shutter instant: (V, 3) float64 camera-space positions, (T,) visibility,
    (NL, LIGHT_WIDTH) light table."""

    positions: np.ndarray
    tri_visible: np.ndarray
    lights: np.ndarray

    @classmethod
    def of(cls, snapshot) -> "Sample":
        """The Sample of a usd.scene.Snapshot (its positions, visibility and lights)."""
        return cls(snapshot.positions, snapshot.tri_visible, snapshot.lights)


@dataclass
class Face:
    """One depth image of a light: rotation from the light's local frame (rows: face axes),
    window on the plane at distance 1 (scene units when orthographic), near depth."""

    rotation: np.ndarray
    window: tuple[float, float, float, float]
    ortho: bool
    near: float
    #: one of cube_faces: rows signed unit axes, a square window about its axis, so a lookup can
    #: tell from light-local coordinates alone whether a point is inside (shadow_lookup.face_coords)
    cube: bool = False

    def projection(self, size: int) -> Projection:
        return Projection(self.ortho, self.window, self.near, FAR, size, size)


@dataclass
class LightLayout:
    """A shadowing light's samples (light-local offsets, (M, 3)) and faces."""

    row: int
    kind: int
    offsets: np.ndarray
    faces: list[Face]
    static: bool = True                # nothing moves in the light's view: one map serves the shutter
    warp: bool | None = None           # auto mode: maps warped (True) or rendered (False), once decided


@dataclass
class KeyMesh:
    """A key face's control points (N nodes: key triangle, barycentrics, depth, source texel
    position), mesh triangles as node triples (P, 3), and the cut cells' texels (n, with their
    own triangle, barycentrics and depth)."""

    node_tri: np.ndarray
    node_bary: np.ndarray
    node_depth: np.ndarray
    node_src: np.ndarray
    tri_nodes: np.ndarray
    texel_xy: np.ndarray
    texel_tri: np.ndarray
    texel_bary: np.ndarray
    texel_depth: np.ndarray


@dataclass
class ShadowData:
    """Maps ready for shading: maps (N, S, S) float32 (None when they were rendered straight into
    texel_major), faces (N, FACE_WIDTH), lights (NL, 3) int32 [first map or -1, samples, faces],
    times B, and the frame's counters (for the share of varying texels, recorded when `varying`
    is first needed)."""

    maps: np.ndarray | None
    faces: np.ndarray
    lights: np.ndarray
    times: int
    size: int
    counters: dict | None = None
    device_arrays: dict = field(default_factory=dict)   # (device, layout) -> uploaded (maps, varying, faces, slot lights)
    #: the maps already laid out for spans of time, when asked for
    texel_major: TexelMajorLayout | None = None
    _varying: np.ndarray | None = field(default=None, repr=False)

    def instant_maps(self) -> np.ndarray:
        """(N, S, S): the maps in map order, each instant's image whole (made from texel_major
        when the maps were rendered straight into it)."""
        if self.maps is None:
            assert self.texel_major is not None
            self.maps = self.texel_major.instant_maps()
        return self.maps

    @property
    def varying(self) -> np.ndarray | None:
        """(N, S, S) uint8: 1 where a texel's depth is not the same in all B maps of its light
        sample and face (a span of time over a texel that never varies needs one lookup, not one
        per instant); None for one instant. Computed when first asked for: only shading over
        spans of time (not a sharp instant's) reads it."""
        if self.times <= 1:
            return None
        if self._varying is None:
            self._varying = varying_texels(self.instant_maps(), self.lights, self.times)
            if self.counters is not None:
                self.counters["shadow_texels_varying"] = float(self._varying.mean()) if self._varying.size else 0.0
        return self._varying


def varying_texels(maps: np.ndarray, lights: np.ndarray, times: int) -> np.ndarray:
    """(N, S, S) uint8 flags of texels whose depth differs between the `times` maps of the same
    light sample and face (maps of light j, sample m, time b, face f at first + (m B + b) F + f)."""
    out = np.zeros(maps.shape, np.uint8)
    for first, samples, faces in lights:
        if first < 0:
            continue
        for m in range(samples):
            for f in range(faces):
                start = first + m * times * faces + f
                out[start:start + times * faces:faces] = face_varying(maps[start:start + times * faces:faces])
    return out


def face_varying(stack: np.ndarray) -> np.ndarray:
    """(S, S) bool: texels whose depth differs between the B maps stack (B, S, S) of one light
    sample and face (compared one map at a time: no temporaries the size of all of them)."""
    changed = np.zeros(stack.shape[1:], bool)
    differs = np.empty(stack.shape[1:], bool)
    for i in range(1, len(stack)):
        np.not_equal(stack[i], stack[0], out=differs)
        changed |= differs
    return changed


def light_frame(row: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """(origin (3,), axes (3, 3): rows = the light's local x, y, z in camera space) from a table row
    (read-only arrays, remembered per row: a frame asks for the same few rows tens of times, and
    NumPy's cost on 3-vectors is its per-call overhead)."""
    row = np.asarray(row)
    return _light_frame(row.tobytes(), row.dtype.str)


@functools.lru_cache(maxsize=256)
def _light_frame(data: bytes, dtype: str) -> tuple[np.ndarray, np.ndarray]:
    origin, axes = _compute_light_frame(np.frombuffer(data, dtype))
    origin.flags.writeable = False
    axes.flags.writeable = False
    return origin, axes


def _compute_light_frame(row: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    origin = np.array(row[4:7], np.float64)
    x = np.asarray(row[10:13], np.float64)
    y = np.asarray(row[13:16], np.float64)
    if np.linalg.norm(x) < 1e-30 or np.linalg.norm(y) < 1e-30:
        z = -np.asarray(row[7:10], np.float64) if int(row[0]) in (RECT, DISK) else np.asarray(row[7:10], np.float64)
        z = z / max(np.linalg.norm(z), 1e-30) if np.linalg.norm(z) > 0 else np.array([0.0, 0.0, 1.0])
        x = perpendicular(z)
        y = np.cross(z, x)
    x = x / np.linalg.norm(x)
    y = y - np.dot(y, x) * x
    y = y / np.linalg.norm(y)
    return origin, np.stack([x, y, np.cross(x, y)])


def perpendicular(v: np.ndarray) -> np.ndarray:
    """A unit vector perpendicular to unit v."""
    a = np.array([1.0, 0.0, 0.0]) if abs(v[0]) < 0.9 else np.array([0.0, 1.0, 0.0])
    p = np.cross(v, a)
    return p / np.linalg.norm(p)


def sample_pattern(m: int) -> np.ndarray:
    """(m, 2) points in [-1, 1]²: the centre for 1, a stratified grid for squares, else a
    Fibonacci spiral in the unit disk."""
    if m <= 1:
        return np.zeros((1, 2))
    n = int(round(np.sqrt(m)))
    if n * n == m:
        c = (np.arange(n) + 0.5) / n * 2 - 1
        gx, gy = np.meshgrid(c, c)
        return np.stack([gx.ravel(), gy.ravel()], axis=1)
    k = np.arange(m)
    r = np.sqrt((k + 0.5) / m)
    phi = k * np.pi * (3 - np.sqrt(5))
    return np.stack([r * np.cos(phi), r * np.sin(phi)], axis=1)


def light_sample_offsets(row: np.ndarray, count: int, towards: np.ndarray) -> np.ndarray:
    """(M, 3) light-local offsets of an area light's samples; `towards` is the light-local
    direction to the geometry (a sphere light is sampled on the disk facing it)."""
    kind = int(row[0])
    if kind == RECT:
        pts = sample_pattern(count)
        w, h = np.linalg.norm(row[10:13]), np.linalg.norm(row[13:16])
        return np.stack([pts[:, 0] * w, pts[:, 1] * h, np.zeros(len(pts))], axis=1)
    if kind == DISK:
        pts = sample_pattern(count)
        if len(pts) > 1 and int(round(np.sqrt(count))) ** 2 == count:  # square grid -> disk (concentric map)
            pts = concentric_disk(pts)
        r = np.linalg.norm(row[10:13])
        return np.stack([pts[:, 0] * r, pts[:, 1] * r, np.zeros(len(pts))], axis=1)
    if kind == SPHERE and row[16] > 0:
        pts = sample_pattern(count)
        if len(pts) > 1 and int(round(np.sqrt(count))) ** 2 == count:
            pts = concentric_disk(pts)
        e1 = perpendicular(towards)
        e2 = np.cross(towards, e1)
        return float(row[16]) * (pts[:, :1] * e1 + pts[:, 1:2] * e2)
    return np.zeros((1, 3))


def concentric_disk(pts: np.ndarray) -> np.ndarray:
    """Shirley's concentric map of [-1, 1]² onto the unit disk."""
    a, b = pts[:, 0], pts[:, 1]
    out = np.zeros_like(pts)
    big_a = np.abs(a) >= np.abs(b)
    with np.errstate(divide="ignore", invalid="ignore"):
        r = np.where(big_a, a, b)
        phi = np.where(big_a, (np.pi / 4) * np.where(a != 0, b / a, 0), np.pi / 2 - (np.pi / 4) * np.where(b != 0, a / b, 0))
    out[:, 0] = r * np.cos(phi)
    out[:, 1] = r * np.sin(phi)
    return out


def cube_faces(size: int) -> list[Face]:
    """Six 90° faces looking down ±x, ±y, ±z of the light's frame (windows padded by a texel)."""
    pad = 1.0 + 2.0 / size
    faces = []
    for axis in range(3):
        for sign in (1.0, -1.0):
            z = np.zeros(3)
            z[axis] = -sign   # the face looks down its -z: towards sign * axis
            x = perpendicular(z)
            faces.append(Face(np.stack([x, np.cross(z, x), z]), (-pad, -pad, pad, pad), False, 0.0, cube=True))
    return faces


def distant_face(lo: np.ndarray, hi: np.ndarray) -> Face:
    """A distant light's one face, around light-local x, y bounds lo (2,) and hi (2,) of the geometry."""
    pad = 0.02 * float((hi - lo).max()) + 1e-6
    return Face(np.eye(3), (lo[0] - pad, lo[1] - pad, hi[0] + pad, hi[1] + pad), True, -FAR)


def fit_faces(kind: int, local: np.ndarray, size: int) -> list[Face]:
    """Faces of a light from light-local points (N, 3) of the geometry (all samples, probes)."""
    if kind == DISTANT:
        return [distant_face(local[:, :2].min(axis=0), local[:, :2].max(axis=0))]
    dist = np.linalg.norm(local, axis=1)
    scale = float(dist.max()) if len(dist) else 1.0
    use = dist > 1e-9 * scale
    dirs = local[use] / dist[use, None]
    mean = dirs.sum(axis=0)
    if np.linalg.norm(mean) > 1e-9 and (dirs @ (mean / np.linalg.norm(mean))).min() > MAX_FRUSTUM_HALF_ANGLE_COS:
        axis = mean / np.linalg.norm(mean)
        z = -axis
        x = perpendicular(z)
        rot = np.stack([x, np.cross(z, x), z])
        q = local[use] @ rot.T
        depth = -q[:, 2]
        wx, wy = q[:, 0] / depth, q[:, 1] / depth
        pad = 0.03 * max(float(wx.max() - wx.min()), float(wy.max() - wy.min())) + 1e-6
        near = max(0.5 * float(depth.min()), 1e-6 * scale)
        return [Face(rot, (wx.min() - pad, wy.min() - pad, wx.max() + pad, wy.max() + pad), False, near)]
    # a cube, without the faces that no geometry lies in
    faces = []
    for f in cube_faces(size):
        q = local[use] @ f.rotation.T
        depth = -q[:, 2]
        inside = (depth > 0) & (np.abs(q[:, 0]) <= depth * f.window[2]) & (np.abs(q[:, 1]) <= depth * f.window[2])
        if inside.any():
            f.near = 1e-5 * scale
            faces.append(f)
    return faces

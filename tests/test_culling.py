"""Back-face culling of closed opaque surfaces (raster/culling.py): which surfaces count as closed,
which triangles may be dropped (against a brute-force facing test over the span), and that
dropping them changes no image in any method."""

import numpy as np
import pytest
from authoring import add_camera, add_distant_light, add_material, add_mesh, new_stage
from pxr import UsdGeom

import warp_blur as wb
import warp_blur.methods.analytic.segments as segments
import warp_blur.methods.frame as frame
from warp_blur.raster.culling import hidden_back_faces
from warp_blur.usd import tessellate
from warp_blur.usd.tessellate import is_closed_surface

CUBE_POINTS = np.array([(x, y, z) for x in (-1, 1) for y in (-1, 1) for z in (-1, 1)], np.float64)
# outward (counter-clockwise seen from outside) quads, split into triangles
CUBE_QUADS = [[0, 1, 3, 2], [4, 6, 7, 5], [0, 4, 5, 1], [2, 3, 7, 6], [0, 2, 6, 4], [1, 5, 7, 3]]
CUBE_TRIS = np.array([t for q in CUBE_QUADS for t in ([q[0], q[1], q[2]], [q[0], q[2], q[3]])], np.int64)


@pytest.mark.parametrize("small", [64, 0], ids=["python", "numpy"])
def test_closed_surfaces_are_told_from_open_and_misoriented_ones(monkeypatch, small):
    monkeypatch.setattr(tessellate, "SMALL_SURFACE_TRIANGLES", small)
    assert is_closed_surface(CUBE_TRIS, CUBE_POINTS)
    assert not is_closed_surface(CUBE_TRIS[:-2], CUBE_POINTS)                  # a face missing
    flipped = CUBE_TRIS.copy()
    flipped[0] = flipped[0][::-1]
    assert not is_closed_surface(flipped, CUBE_POINTS)                         # one triangle wound backwards
    # a seam: the first face's corners are copies of the points (same positions): still closed
    seam_points = np.concatenate([CUBE_POINTS, CUBE_POINTS[CUBE_QUADS[0]]])
    seam = CUBE_TRIS.copy()
    for i, v in enumerate(CUBE_QUADS[0]):
        seam[:2][seam[:2] == v] = 8 + i
    assert is_closed_surface(seam, seam_points)


def test_small_surfaces_are_judged_in_python_as_numpy_judges_them(monkeypatch):
    """Random edits of a cube with a seam (faces dropped, flipped, repeated, collapsed; corners
    moved onto others or to -0.0): the plain-Python test for small surfaces agrees with NumPy's."""
    rng = np.random.default_rng(3)
    seam_points = np.concatenate([CUBE_POINTS, CUBE_POINTS[CUBE_QUADS[0]]])
    seam = CUBE_TRIS.copy()
    for i, v in enumerate(CUBE_QUADS[0]):
        seam[:2][seam[:2] == v] = 8 + i
    verdicts = []
    for _ in range(400):
        tris, points = seam.copy(), seam_points.copy()
        for _edit in range(rng.integers(0, 3)):
            kind = rng.integers(0, 5)
            t = rng.integers(0, len(tris))
            if kind == 0:
                tris = np.delete(tris, t, axis=0)
            elif kind == 1:
                tris[t] = tris[t][::-1]
            elif kind == 2:
                tris = np.concatenate([tris, tris[t:t + 1]])
            elif kind == 3:
                tris[t, rng.integers(0, 3)] = tris[t, rng.integers(0, 3)]
            else:
                points[rng.integers(0, len(points))] = points[rng.integers(0, len(points))] * np.array([1.0, 1.0, -1.0]) \
                    if rng.integers(0, 2) else points[rng.integers(0, len(points))]
        if rng.integers(0, 4) == 0:
            points = np.where(points == 0.0, -0.0, points)
        monkeypatch.setattr(tessellate, "SMALL_SURFACE_TRIANGLES", 64)
        python = is_closed_surface(tris, points)
        monkeypatch.setattr(tessellate, "SMALL_SURFACE_TRIANGLES", 0)
        assert python == is_closed_surface(tris, points)
        verdicts.append(python)
    assert 20 < sum(verdicts) < 380   # both verdicts are common among the edits


def _facing_over_span(a0, a1, steps=2001) -> np.ndarray:
    """(steps,) det[a(t), b(t), c(t)] of a triangle (3, 3) moving linearly from a0 to a1."""
    t = np.linspace(0, 1, steps)[:, None, None]
    p = a0[None] * (1 - t) + a1[None] * t
    return np.linalg.det(p)


def test_only_triangles_facing_away_over_their_whole_span_are_dropped():
    """A cube 6 units ahead spinning a quarter turn over one span: a triangle is dropped only if it
    faces away at every instant (brute force over 2001 instants), and most of those are."""
    rng = np.random.default_rng(1)
    for trial in range(20):
        angle = rng.uniform(0, np.pi / 2)
        axis = rng.normal(size=3)
        axis /= np.linalg.norm(axis)
        k = np.array([[0, -axis[2], axis[1]], [axis[2], 0, -axis[0]], [-axis[1], axis[0], 0]])
        rot = np.eye(3) + np.sin(angle) * k + (1 - np.cos(angle)) * k @ k
        offset = np.array([rng.uniform(-2, 2), rng.uniform(-2, 2), -6.0])
        p0 = CUBE_POINTS + offset
        p1 = CUBE_POINTS @ rot.T + offset + rng.uniform(-1, 1, 3)
        positions = np.stack([p0, p1])
        n = len(CUBE_TRIS)
        tri = np.arange(n)
        dropped = hidden_back_faces(positions, CUBE_TRIS, np.zeros(n, np.int64), np.ones(n, bool), tri,
                                    np.zeros(n, np.int64), np.ones(n, np.int64), 0.1, 100.0)
        for t in range(n):
            facing = _facing_over_span(positions[0][CUBE_TRIS[t]], positions[1][CUBE_TRIS[t]])
            if dropped[t]:
                assert (facing > 0).all(), (trial, t)           # outward cube: det > 0 is back-facing
        assert dropped.sum() >= 2
        static = hidden_back_faces(positions[:1], CUBE_TRIS, np.zeros(n, np.int64), np.ones(n, bool), tri,
                                   np.zeros(n, np.int64), np.zeros(n, np.int64), 0.1, 100.0)
        dets = np.linalg.det(positions[0][CUBE_TRIS])
        np.testing.assert_array_equal(static, dets > 0)           # a still cube: exactly its back faces


def test_a_triangle_that_turns_towards_the_eye_mid_span_is_kept():
    """Cubes whose vertices are thrown about between two knots (the instance keeping its outward
    volume at both): a triangle facing away at both knots may face the eye in between (its facing
    is a cubic in time), and is dropped only if it faces away at every instant."""
    rng = np.random.default_rng(7)
    turned = 0
    for trial in range(300):
        p0 = CUBE_POINTS + [0.0, 0.0, -8.0]
        p1 = p0 + rng.normal(0, 1.5, (8, 3))
        if np.linalg.det(p1[CUBE_TRIS]).sum() <= 0:
            continue
        n = len(CUBE_TRIS)
        dropped = hidden_back_faces(np.stack([p0, p1]), CUBE_TRIS, np.zeros(n, np.int64), np.ones(n, bool),
                                    np.arange(n), np.zeros(n, np.int64), np.ones(n, np.int64), 0.1, 100.0)
        for t in range(n):
            facing = _facing_over_span(p0[CUBE_TRIS[t]], p1[CUBE_TRIS[t]])
            if dropped[t]:
                assert (facing > 0).all(), (trial, t)
            elif facing[0] > 0 and facing[-1] > 0 and (facing < 0).any():
                turned += 1
    assert turned >= 5   # the case the middle coefficients are for does occur


def test_nothing_is_dropped_when_the_eye_may_be_inside_or_the_surface_is_clipped_or_mirrored():
    n = len(CUBE_TRIS)
    args = (CUBE_TRIS, np.zeros(n, np.int64), np.ones(n, bool), np.arange(n), np.zeros(n, np.int64),
            np.zeros(n, np.int64))
    inside = (CUBE_POINTS * 5.0)[None]                             # the eye (origin) inside the cube
    assert not hidden_back_faces(inside, *args, 0.1, 100.0).any()
    ahead = (CUBE_POINTS + [0, 0, -6.0])[None]
    assert not hidden_back_faces(ahead, *args, 5.5, 100.0).any()   # the near plane cuts it open
    assert not hidden_back_faces(ahead, *args, 0.1, 6.5).any()     # ... or the far plane
    assert not hidden_back_faces(ahead, CUBE_TRIS, np.zeros(n, np.int64), np.zeros(n, bool), *args[3:],
                                 0.1, 100.0).any()                  # not closed
    mirrored = (CUBE_POINTS * [-1, 1, 1] + [0, 0, -6.0])[None]      # inward-wound now: volume < 0
    dropped = hidden_back_faces(mirrored, *args, 0.1, 100.0)
    np.testing.assert_array_equal(dropped, np.linalg.det(mirrored[0][CUBE_TRIS]) < 0)
    assert dropped.sum() == 10                                     # on its axis: one face seen, five dropped


def _cubes_stage(path: str) -> str:
    """Three lit closed cubes (one spinning, one moving, one mirrored) and an open box behind them."""
    stage = new_stage(path)
    add_camera(stage, translate=(0, 0, 9), shutter=(-0.5, 0.5))
    add_distant_light(stage, "/World/Sun")
    mat = add_material(stage, "/World/Looks/Grey", diffuse=(0.6, 0.6, 0.6))
    counts, indices = [4] * 6, [v for q in CUBE_QUADS for v in q]
    pts = [tuple(p * 0.8) for p in CUBE_POINTS]
    add_mesh(stage, "/World/Spin", pts, counts, indices, material=mat, double_sided=False,
             rotate_axis="Y", rotate_samples={0.5: 0.0, 1.5: 80.0}, translate=(-2.2, 0, 0))
    add_mesh(stage, "/World/Slide", pts, counts, indices, material=mat,
             translate_samples={0.5: (-0.5, -1, 0), 1.5: (0.5, 1, 1)})
    mirror = add_mesh(stage, "/World/Mirror", pts, counts, indices, material=mat, translate=(2.2, 0, 0))
    UsdGeom.Xformable(mirror).AddScaleOp().Set((-1.0, 1.0, 1.0))
    add_mesh(stage, "/World/Open", [tuple(p * 3 + np.array([0, 0, -5])) for p in CUBE_POINTS], [4] * 5,
             indices[4:], material=mat)
    stage.GetRootLayer().Save()
    return path


@pytest.mark.parametrize("method,kw", [("analytic", {}), ("stochastic", {"samples": 16}),
                                       ("accumulation", {"samples": 8})])
def test_dropping_hidden_back_faces_changes_no_image(scene_path, monkeypatch, method, kw):
    path = _cubes_stage(scene_path())
    render = dict(frame=1, method=method, resolution=(64, 48), **kw)
    culled = wb.render(path, **render)
    assert culled.stats["back_faces_dropped"] > 0
    none = lambda *a, **k: np.zeros(len(a[4]), bool)  # noqa: E731
    monkeypatch.setattr(segments, "hidden_back_faces", none, raising=False)
    monkeypatch.setattr(frame, "hidden_back_faces", none)
    kept = wb.render(path, **render)
    assert np.abs(culled.rgba - kept.rgba).max() < 2e-3

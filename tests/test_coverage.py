"""The analytic coverage's per-entry edge tables (coverage.edge_table) against the edge
quadratics computed per ray (prism_edges), and renders with and without them."""

import os

import numpy as np
import warp as wp
from conftest import SCENES

import warp_blur as wb
from warp_blur.methods.analytic.coverage import (DEGENERATE_TOL_F32, EDGE_TABLE_WIDTH, edge_table, prism_edges,
                                                 prism_edges_table)
from warp_blur.output.metrics import max_abs


@wp.kernel(enable_backward=False)
def _both_ways(positions: wp.array2d(dtype=wp.vec3), tri_vertices: wp.array(dtype=wp.vec3i),
               table: wp.array2d(dtype=wp.vec3), dirs: wp.array(dtype=wp.vec3),
               per_ray: wp.array2d(dtype=float), tabled: wp.array2d(dtype=float)):
    """Row i: ray i against triangle i (knots 0 and 1): coefficients, roots and degeneracy flags of
    its three edges, per ray and from the table."""
    i = wp.tid()
    vi = tri_vertices[i]
    d = dirs[i]
    a0 = positions[0, vi[0]]
    b0 = positions[0, vi[1]]
    c0 = positions[0, vi[2]]
    da = positions[1, vi[0]] - a0
    db = positions[1, vi[1]] - b0
    dc = positions[1, vi[2]] - c0
    ca, cb, cc, ra, rb, rc, dga, dgb, dgc = prism_edges(d, a0, da, b0, db, c0, dc, vi, DEGENERATE_TOL_F32)
    ta, tb, tc, sa, sb, sc, ega, egb, egc = prism_edges_table(table, i, d, DEGENERATE_TOL_F32)
    for j in range(3):
        per_ray[i, j] = ca[j]
        per_ray[i, 3 + j] = cb[j]
        per_ray[i, 6 + j] = cc[j]
        tabled[i, j] = ta[j]
        tabled[i, 3 + j] = tb[j]
        tabled[i, 6 + j] = tc[j]
    for j in range(2):
        per_ray[i, 9 + j] = ra[j]
        per_ray[i, 11 + j] = rb[j]
        per_ray[i, 13 + j] = rc[j]
        tabled[i, 9 + j] = sa[j]
        tabled[i, 11 + j] = sb[j]
        tabled[i, 13 + j] = sc[j]
    per_ray[i, 15] = float(dga + 2 * dgb + 4 * dgc)
    tabled[i, 15] = float(ega + 2 * egb + 4 * egc)


def test_edge_table_equals_the_edge_quadratics_per_ray():
    """Random moving triangles in front of the eye, each with a ray through it, and one whose
    edge (vertices 0, 1) moves in a plane through the eye with the ray in that plane (a degenerate
    edge): the table gives the same coefficients, roots and degeneracy flags as prism_edges,
    including the canonical sign of edges whose vertex indices run backwards."""
    rng = np.random.default_rng(3)
    n = 200
    p0 = rng.uniform(-2, 2, (n, 3, 3)) + np.array([0.0, 0.0, -8.0])
    p1 = p0 + rng.normal(0, 0.7, (n, 3, 3))
    p0[0] = [(1, 0, -5), (2, 0, -5), (0, 1, -5)]
    p1[0] = [(1, 0, -6), (2, 0, -6), (0, 1.5, -6)]
    positions = np.stack([p0.reshape(-1, 3), p1.reshape(-1, 3)])
    order = np.array([(0, 1, 2), (2, 1, 0), (1, 2, 0)])[rng.integers(0, 3, n)]
    tris = (np.arange(n)[:, None] * 3 + order).astype(np.int32)
    tris[0] = (0, 1, 2)
    centre = (p0.mean(1) + p1.mean(1)) / 2
    dirs = centre / -centre[:, 2:3]
    dirs[0] = (0.3, 0.0, -1.0)
    pos = wp.array(positions.astype(np.float32), dtype=wp.vec3)
    tri = wp.array(tris, dtype=wp.vec3i)
    idx = wp.array(np.arange(n, dtype=np.int32), dtype=int)
    k0 = wp.zeros(n, dtype=int)
    k1 = wp.array(np.ones(n, np.int32), dtype=int)
    table = wp.zeros((n, EDGE_TABLE_WIDTH), dtype=wp.vec3)
    wp.launch(edge_table, dim=n, inputs=[pos, tri, idx, k0, k1], outputs=[table])
    per_ray = wp.zeros((n, 16), dtype=float)
    tabled = wp.zeros((n, 16), dtype=float)
    wp.launch(_both_ways, dim=n, inputs=[pos, tri, table, wp.array(dirs.astype(np.float32), dtype=wp.vec3)],
              outputs=[per_ray, tabled])
    a, b = per_ray.numpy(), tabled.numpy()
    assert a[0, 15] == 1.0   # the edge in the eye's plane is degenerate, the others are not
    assert (a[1:, 15] == 0).all()
    np.testing.assert_array_equal(a[:, 15], b[:, 15])
    scale = np.abs(a[:, :9]).max(axis=1, keepdims=True)
    assert np.abs(a[:, :9] - b[:, :9]).max() <= 1e-6 * scale.max()
    assert (np.abs(a[:, :9] - b[:, :9]) <= 1e-6 * scale).all()
    assert np.abs(a[:, 9:15] - b[:, 9:15]).max() <= 1e-5


#: scenes rendered with a table switched on and off: a spinning cube in 8 motion segments with a
#: moving camera (analytic and stochastic) and triangles crossing the near plane (analytic)
TABLE_CASES = [("demo.usda", 12.0, "analytic"), ("near_plane.usda", 2.0, "analytic"), ("demo.usda", 12.0, "stochastic")]


def _switched_renders(monkeypatch, switch: str, **extra):
    """(scene, render with segments.<switch> on, render with it off) for each of TABLE_CASES at 96x72."""
    import warp_blur.methods.analytic.segments as segments
    for name, frame, method in TABLE_CASES:
        kw = dict(frame=frame, resolution=(96, 72), method=method, aovs=(), **extra)
        if method == "stochastic":
            kw["samples"] = 8
        path = os.path.join(SCENES, name)
        monkeypatch.setattr(segments, switch, True)
        on = wb.render(path, **kw)
        monkeypatch.setattr(segments, switch, False)
        yield name, on, wb.render(path, **kw)


def test_renders_with_edge_tables_equal_renders_computing_edges_per_ray(monkeypatch):
    """TABLE_CASES with shadows off: coverage from the entries' edge tables gives the image and
    interval count of coverage computed per ray."""
    for name, tabled, per_ray in _switched_renders(monkeypatch, "EDGE_TABLES", shadows="off"):
        assert max_abs(tabled.rgba, per_ray.rgba) <= 1e-6, name
        assert tabled.stats.get("intervals") == per_ray.stats.get("intervals")


def test_renders_with_corner_tables_equal_renders_gathering_positions(monkeypatch):
    """TABLE_CASES with their shadows: entries read from the frame's corner table (one row of six
    vertices an entry) give, bit for bit, the image and interval count of entries gathered from
    the positions through their triangle's vertex indices."""
    for name, tabled, gathered in _switched_renders(monkeypatch, "CORNER_TABLES"):
        np.testing.assert_array_equal(tabled.rgba, gathered.rgba, err_msg=name)
        assert tabled.stats.get("intervals") == gathered.stats.get("intervals")

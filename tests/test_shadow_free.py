"""Entries no shadow can fall on (shadows/free_entries.py, kernels/shadow_free.py): shading skips
their lookups, so the flags must be conservative. Checked against the lookups themselves (an
oracle kernel samples flagged parts of entries at random times, normals and spans and looks each
up) and by rendering with and without the skip."""

from __future__ import annotations

import os

import numpy as np
import pytest
import warp as wp
from conftest import SCENES

import warp_blur as wb
from warp_blur.kernels.kernel_types import Geometry, Shading
from warp_blur.kernels.shading import entry_point_velocity
from warp_blur.kernels.rays import entry_vertex
from warp_blur.kernels.shadow_free import CELLS, cell_of
from warp_blur.kernels.shadow_lookup import light_visibility
from warp_blur.shadows import free_entries

RES = (96, 72)
CASES = [("demo", 12.0), ("shadows", 6.0)]


@wp.kernel(enable_backward=False)
def sampled_visibility(geo: Geometry, sh: Shading, flags: wp.array(dtype=int), want_flagged: int, seed: int,
                       samples: int, sharp_at: float, lowest: wp.array(dtype=float), count: wp.array(dtype=int)):
    """For entry tid: `samples` random points of it (random barycentrics, time in its span, unit
    normal, shadow span du), each looked up for every light whose flag for the point's cell is
    (want_flagged 1) or is not (0) set; lowest[j] / count[j] gather the visibilities seen.
    sharp_at >= 0: a sharp instant's static entries, looked up at that time with no span."""
    e = wp.tid()
    nl = sh.num_lights
    state = wp.rand_init(seed, e)
    vi = geo.tri_vertices[geo.entry_tri[e]]
    k0 = geo.entry_k0[e]
    k1 = geo.entry_k1[e]
    for _s in range(samples):
        wb = wp.randf(state)
        wc = wp.randf(state)
        if wb + wc > 1.0:
            wb = 1.0 - wb
            wc = 1.0 - wc
        cell = cell_of(wb, wc)
        u = wp.randf(state)
        alpha = float(0.0)
        if sharp_at >= 0.0:
            u = sharp_at
        elif k0 != k1:
            alpha = wp.randf(state)
            u = (float(k0) + alpha * float(k1 - k0)) / float(geo.num_segments)
        p = (1.0 - wb - wc) * entry_vertex(geo, e, vi[0], alpha) + wb * entry_vertex(geo, e, vi[1], alpha) \
            + wc * entry_vertex(geo, e, vi[2], alpha)
        vel = entry_point_velocity(geo, e, vi, wp.vec4(0.0, 0.0, wb, wc))
        n = wp.normalize(wp.vec3(wp.randn(state), wp.randn(state), wp.randn(state)))
        du = float(0.0)
        if sharp_at < 0.0 and wp.randf(state) < 0.5:
            du = 0.4 * wp.randf(state)
        for j in range(nl):
            flagged = ((flags[e * nl + j] >> cell) & 1) != 0
            if flagged == (want_flagged != 0):
                v = light_visibility(sh, j, u, du, p, vel, n)
                wp.atomic_min(lowest, j, v)
                wp.atomic_add(count, j, 1)


def capture_flags(monkeypatch) -> list:
    """Record each frame's (Shading, Geometry, entry count) as flags are set for it."""
    seen = []
    original = free_entries.flag_shadow_free

    def recording(sh, occ, geo, num_entries, device, counters=None, sharp_at=None):
        original(sh, occ, geo, num_entries, device, counters, sharp_at)
        seen.append((sh, geo, num_entries, sharp_at))
    monkeypatch.setattr(free_entries, "flag_shadow_free", recording)
    return seen


def looked_up(sh, geo, num_entries, want_flagged: bool, samples: int = 64, seed: int = 5, sharp_at=None):
    lowest = wp.full(sh.num_lights, 2.0, dtype=float, device="cpu")
    count = wp.zeros(sh.num_lights, dtype=int, device="cpu")
    at = -1.0 if sharp_at is None else float(sharp_at)
    wp.launch(sampled_visibility, dim=num_entries,
              inputs=[geo, sh, geo.shadow_free, int(want_flagged), seed, samples, at, lowest, count], device="cpu")
    return lowest.numpy(), count.numpy()


@pytest.mark.parametrize("scene,frame", CASES)
def test_flagged_parts_of_a_sharp_instant_are_lit_by_every_lookup(monkeypatch, scene, frame):
    """Accumulation flags each instant's entries against the maps it reads (the two map instants
    around it, its points moved with the vertices' velocities)."""
    monkeypatch.setattr(free_entries, "BLOCK", 1)
    seen = capture_flags(monkeypatch)
    wb.render(os.path.join(SCENES, f"{scene}.usda"), frame=frame, method="accumulation", samples=16,
              resolution=RES, aovs=())
    assert seen and all(at is not None for *_, at in seen)
    lit_seen = shadowed = 0
    for sh, geo, num_entries, at in seen:
        if geo.shadow_free.shape[0] != num_entries * sh.num_lights:
            continue   # nothing flagged at this instant
        lowest, count = looked_up(sh, geo, num_entries, want_flagged=True, samples=16, sharp_at=at)
        for j in range(sh.num_lights):
            if count[j]:
                lit_seen += int(count[j])
                assert lowest[j] >= 1.0 - 1e-5, f"light {j} at {at}: a flagged point looked up {lowest[j]}"
        lowest, count = looked_up(sh, geo, num_entries, want_flagged=False, samples=16, sharp_at=at)
        shadowed += int((lowest[count > 0] < 0.5).any())
    assert lit_seen > 1000 and shadowed > 0


@pytest.mark.parametrize("block", [1, free_entries.BLOCK])
@pytest.mark.parametrize("scene,frame", CASES)
def test_flagged_parts_of_entries_are_lit_by_every_lookup(monkeypatch, scene, frame, block):
    # block 1: occupancy per texel, so only the margins the test adds keep it conservative
    monkeypatch.setattr(free_entries, "BLOCK", block)
    seen = capture_flags(monkeypatch)
    wb.render(os.path.join(SCENES, f"{scene}.usda"), frame=frame, method="analytic", resolution=RES, aovs=())
    assert seen, "the frame's entries were never tested"
    sh, geo, num_entries, _ = seen[-1]
    flags = geo.shadow_free.numpy().reshape(num_entries, sh.num_lights)
    shadowing = [j for j in range(sh.num_lights) if sh.shadow_lights.numpy()[j, 0] >= 0]
    assert all(np.count_nonzero(flags[:, j]) > 0 for j in shadowing), "no entry flagged for a shadowing light"
    lowest, count = looked_up(sh, geo, num_entries, want_flagged=True)
    for j in shadowing:
        assert count[j] > 1000
        # lit: every tap compared lit (the bilinear weights sum to 1 within a rounding)
        assert lowest[j] >= 1.0 - 1e-5, f"light {j}: a flagged point looked up {lowest[j]}"
    # the oracle sees shadows where nothing is flagged (it is able to fail)
    lowest, count = looked_up(sh, geo, num_entries, want_flagged=False)
    assert min(lowest[j] for j in shadowing) < 0.5


def test_cells_cover_the_triangle_and_pick_the_cell_a_point_lies_in():
    @wp.kernel
    def cells(points: wp.array(dtype=wp.vec2), out: wp.array(dtype=int)):
        i = wp.tid()
        out[i] = cell_of(points[i][0], points[i][1])

    rng = np.random.default_rng(3)
    pts = rng.uniform(0, 1, (4000, 2)).astype(np.float32)
    pts = np.where(pts.sum(axis=1, keepdims=True) > 1, 1 - pts, pts)
    edge = np.array([[1.0, 0.0], [0.0, 1.0], [0.5, 0.5], [0.25, 0.75], [0.0, 0.0], [1.0000001, 0.0]], np.float32)
    pts = np.concatenate([pts, edge])
    out = wp.zeros(len(pts), dtype=int, device="cpu")
    wp.launch(cells, dim=len(pts), inputs=[wp.array(pts, dtype=wp.vec2, device="cpu"), out], device="cpu")
    got = out.numpy()
    i, k = got // CELLS, got % CELLS
    assert (i + k <= CELLS - 1).all() and got.min() >= 0
    # the cell (i, k) holds w_b in [i, i+1] / n and w_c in [k, k+1] / n (within rounding)
    tol = 1e-6
    assert (pts[:, 0] >= i / CELLS - tol).all() and (pts[:, 0] <= (i + 1) / CELLS + tol).all()
    assert (pts[:, 1] >= k / CELLS - tol).all() and (pts[:, 1] <= (k + 1) / CELLS + tol).all()
    assert len(set(got.tolist())) == CELLS * (CELLS + 1) // 2


@pytest.mark.parametrize("method", ["analytic", "stochastic", "accumulation"])
@pytest.mark.parametrize("scene,frame", CASES)
def test_skipping_lookups_changes_the_image_by_rounding_only(monkeypatch, scene, frame, method):
    path = os.path.join(SCENES, f"{scene}.usda")
    kw = {"samples": 8} if method != "analytic" else {}
    got = wb.render(path, frame=frame, method=method, resolution=RES, aovs=(), **kw)
    assert got.stats["shadow_free_entries"] > 0
    monkeypatch.setattr(free_entries, "SKIP_SHADOW_FREE", False)
    ref = wb.render(path, frame=frame, method=method, resolution=RES, aovs=(), **kw)
    assert "shadow_free_entries" not in ref.stats
    assert np.abs(got.rgba - ref.rgba).max() <= 1e-6 * max(1.0, float(np.abs(ref.rgba).max()))


def test_frames_past_the_flag_budget_look_every_lookup_up(monkeypatch):
    monkeypatch.setattr(free_entries, "MAX_FLAGS", 10)
    got = wb.render(os.path.join(SCENES, "demo.usda"), frame=12.0, method="analytic", resolution=(32, 24), aovs=())
    assert "shadow_free_entries" not in got.stats


@pytest.mark.parametrize("scene,frame,mode", [("demo", 12.0, "auto"), ("shadows", 6.0, "auto"),
                                              ("demo", 12.0, "warped")])
def test_occupancy_marked_as_the_maps_are_written_equals_reading_them(monkeypatch, scene, frame, mode):
    """The time-continuous methods' maps mark their occupied blocks as they are written (the
    moving casters' splat, the still base filled in, warped maps put in place), so the occupancy
    pass need not read every texel of every instant again: the tables must equal the ones found
    by reading them."""
    original = free_entries.occupancy_table
    compared = []

    def both(sh, device, threads, blocks=None):
        marked = original(sh, device, threads, blocks)
        read = original(sh, device, threads, None)
        compared.append((blocks is not None, np.array_equal(marked.numpy(), read.numpy()),
                         int(read.numpy()[:, -1, -1].sum())))
        return marked
    monkeypatch.setattr(free_entries, "occupancy_table", both)
    wb.render(os.path.join(SCENES, f"{scene}.usda"), frame=frame, method="analytic", resolution=RES, aovs=(),
              shadows=mode)
    assert compared, "no occupancy was found"
    for was_marked, equal, occupied_blocks in compared:
        assert was_marked and occupied_blocks > 0
        assert equal, "the blocks marked while the maps were written differ from the maps read"

"""Shadow-map lookups over a time span (kernels/shadow_lookup.py): where a light and the receiver
hold still, light_visibility finds each sample's face and texel coordinates once and reads only
the map instants per step (still_span_visibility). Checked against the per-step lookups it
replaces, at random points, spans and normals of a frame's still entries under a moving shadow."""

from __future__ import annotations

import pytest
import warp as wp
from scenes import shadow_stage

import warp_blur as wb
from warp_blur.kernels.kernel_types import Geometry, Shading
from warp_blur.kernels.rays import entry_vertex
from warp_blur.kernels.shading import entry_point_velocity
from warp_blur.kernels.shadow_lookup import light_visibility, light_visibility_at
from warp_blur.shadows import free_entries

MOVING = {0.5: (-1.0, 1.0, 0.0), 1.5: (1.0, 1.0, 0.0)}   # the occluder crosses 2 units in the shutter


@wp.kernel(enable_backward=False)
def span_lookups(geo: Geometry, sh: Shading, seed: int, samples: int,
                 # outputs: per light, the largest |fast - per step|, points looked up, points whose
                 # steps do not all see what the first map instant sees (a moving shadow)
                 worst: wp.array(dtype=float), count: wp.array(dtype=int), varied: wp.array(dtype=int)):
    e = wp.tid()
    if geo.entry_k0[e] != geo.entry_k1[e]:
        return
    state = wp.rand_init(seed, e)
    vi = geo.tri_vertices[geo.entry_tri[e]]
    for _s in range(samples):
        wb_ = wp.randf(state)
        wc = wp.randf(state)
        if wb_ + wc > 1.0:
            wb_ = 1.0 - wb_
            wc = 1.0 - wc
        p = (1.0 - wb_ - wc) * entry_vertex(geo, e, vi[0], 0.0) + wb_ * entry_vertex(geo, e, vi[1], 0.0) \
            + wc * entry_vertex(geo, e, vi[2], 0.0)
        vel = entry_point_velocity(geo, e, vi, wp.vec4(0.0, 0.0, wb_, wc))
        n = wp.normalize(wp.vec3(wp.randn(state), wp.randn(state), wp.randn(state)))
        du = 0.1 + 0.9 * wp.randf(state)
        u = 0.5 * du + (1.0 - du) * wp.randf(state)
        steps = wp.clamp(int(wp.ceil(du * float(sh.shadow_times))), 1, sh.shadow_times)
        for j in range(sh.num_lights):
            fast = light_visibility(sh, j, u, du, p, vel, n)
            total = float(0.0)
            first = light_visibility_at(sh, j, 0.5 / float(sh.shadow_times), p, vel, n)
            moved = int(0)
            for i in range(steps):
                ui = u - 0.5 * du + du * (float(i) + 0.5) / float(steps)
                v = light_visibility_at(sh, j, ui, p + (ui - u) * vel, vel, n)
                if v != first:
                    moved = 1
                total += v
            wp.atomic_max(worst, j, wp.abs(fast - total / float(steps)))
            wp.atomic_add(count, j, 1)
            wp.atomic_add(varied, j, moved)


@pytest.mark.parametrize("light,size", [("distant", 0.0), ("sphere", 0.3)])
def test_still_span_lookups_equal_the_lookups_of_every_step(scene_path, monkeypatch, light, size):
    path = shadow_stage(scene_path(), occluder_samples=MOVING, light=light, light_size=size)
    seen = []
    original = free_entries.flag_shadow_free

    def recording(sh, occ, geo, num_entries, device, counters=None, sharp_at=None):
        original(sh, occ, geo, num_entries, device, counters, sharp_at)
        seen.append((sh, geo, num_entries))
    monkeypatch.setattr(free_entries, "flag_shadow_free", recording)
    wb.render(path, frame=1, method="analytic", resolution=(64, 48), shadows="direct", shadow_map_size=128,
              light_samples=1 if light == "distant" else 4)
    sh, geo, num_entries = seen[-1]
    assert sh.shadow_times > 1 and sh.shadow_lights.numpy()[0, 3] == 1   # a still light, several map instants
    worst = wp.zeros(sh.num_lights, dtype=float, device="cpu")
    count = wp.zeros(sh.num_lights, dtype=int, device="cpu")
    varied = wp.zeros(sh.num_lights, dtype=int, device="cpu")
    wp.launch(span_lookups, dim=num_entries, inputs=[geo, sh, 7, 2000], outputs=[worst, count, varied], device="cpu")
    assert int(sh.shadow_lights.numpy()[0, 1]) == (1 if light == "distant" else 4)   # light samples
    assert count.numpy()[0] >= 2000 and varied.numpy()[0] >= 20   # the moving shadow is among them
    # rounding only: where no step's texels change, one lookup stands for the mean of equal values,
    # and several light samples are summed over the samples first
    assert worst.numpy()[0] <= 1e-6, worst.numpy()

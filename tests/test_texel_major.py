"""shadows/texel_major.py: maps put into the texel-major layout one at a time, or a face filled
with a base, equal the whole frame's layout done afterwards (device_data.face_slots) and its
varying-texel flags; core/reuse.py hands a frame's layout memory to the next frame."""

from __future__ import annotations

import gc

import numpy as np
import pytest

from warp_blur.core import reuse
from warp_blur.raster.device_data import face_slots
from warp_blur.shadows.layout import ShadowData, varying_texels
from warp_blur.shadows.texel_major import TexelMajorLayout

B, S = 4, 16
LIGHTS = [(2, 1), (1, 3)]   # (samples M, faces F) per light


def frame_maps(seed: int) -> tuple[np.ndarray, np.ndarray]:
    """(maps (N, S, S) with most texels the same at every instant, lights (NL, 3) [first, M, F])."""
    rng = np.random.default_rng(seed)
    # each light's maps (M, B, F, S, S), the same at every instant B, then a few texels moved
    maps = np.concatenate([np.repeat(rng.uniform(1, 5, (m, 1, f, S, S)), B, axis=1).reshape(-1, S, S)
                           for m, f in LIGHTS]).astype(np.float32)
    n = len(maps)
    moving = rng.random((n, S, S)) < 0.03
    maps[moving] = rng.uniform(1, 5, moving.sum())
    maps[rng.random((n, S, S)) < 0.05] = np.inf
    lights, first = [], 0
    for m, f in LIGHTS:
        lights.append((first, m, f))
        first += m * B * f
    return maps, np.array(lights, np.int32)


def layout_for(maps: np.ndarray, lights: np.ndarray) -> TexelMajorLayout:
    laid = TexelMajorLayout(len(maps) // B, S, B)
    for first, m, f in lights:
        laid.add_light(int(first), int(m), int(f))
    return laid


@pytest.mark.parametrize("seed", [0, 1])
def test_maps_put_in_any_order_equal_the_whole_layout(seed):
    maps, lights = frame_maps(seed)
    expected, _faces, expected_varying, _lights = face_slots(
        ShadowData(maps, np.zeros((len(maps), 22), np.float32), lights, B, S))
    laid = layout_for(maps, lights)
    for idx in np.random.default_rng(seed).permutation(len(maps)):
        laid.put(int(idx), maps[idx])
    laid.finish()
    np.testing.assert_array_equal(laid.slots, expected)
    np.testing.assert_array_equal(laid.varying, expected_varying)
    assert 0.0 < laid.varying.mean() < 0.5
    np.testing.assert_array_equal(laid.instant_maps(), maps)
    # and the frame's data reads the same maps whichever layout it was built in
    data = ShadowData(None, np.zeros((len(maps), 22), np.float32), lights, B, S, texel_major=laid)
    np.testing.assert_array_equal(data.instant_maps(), maps)
    np.testing.assert_array_equal(data.varying, varying_texels(maps, lights, B))


def test_a_base_fills_the_chosen_instants_and_a_put_map_the_rest():
    maps, lights = frame_maps(0)
    laid = layout_for(maps, lights)
    base = np.arange(S * S, dtype=np.float32).reshape(S, S)
    laid.fill(4, [1, 2, 3], base)              # slot 4: the second light's last face
    laid.put(8 + 0 * 3 + 2, maps[8 + 2])        # its instant 0, made on its own
    np.testing.assert_array_equal(laid.slots[4][..., 0], maps[10])
    for b in (1, 2, 3):
        np.testing.assert_array_equal(laid.slots[4][..., b], base)
    laid.flag(4)
    np.testing.assert_array_equal(laid.varying[4], maps[10] != base)
    laid.fill(0, list(range(B)), None)          # a whole face, empty
    assert np.isinf(laid.slots[0]).all()


def test_a_map_of_no_registered_light_is_an_error():
    maps, lights = frame_maps(0)
    laid = TexelMajorLayout(len(maps) // B, S, B)
    laid.add_light(0, 2, 1)
    with pytest.raises(IndexError):
        laid.put(len(maps) - 1, maps[0])


def test_a_frames_layout_memory_is_reused_only_once_every_reader_is_gone():
    gc.collect()    # earlier tests' frames hand their arrays back first (they would push this test's out)
    reuse.clear()
    a = reuse.reused_empty((3, 8, 8, 4), float)
    b = reuse.reused_empty((3, 8, 8, 4), float)
    assert a.ptr != b.ptr                       # both frames alive: two arrays
    ptr = a.ptr
    reader = a.numpy()                          # a pass still reading the first frame's maps
    del a
    gc.collect()
    c = reuse.reused_empty((3, 8, 8, 4), float)
    assert c.ptr not in (ptr, b.ptr)            # not handed on while it is read
    del reader
    gc.collect()
    d = reuse.reused_empty((3, 8, 8, 4), float)
    assert d.ptr == ptr                         # the first frame's memory, handed on
    e = reuse.reused_empty((2, 8, 8, 4), float)
    assert e.ptr not in (ptr, b.ptr, c.ptr) and e.shape == (2, 8, 8, 4)
    reuse.clear()


@pytest.mark.parametrize("method, samples", [("accumulation", 16), ("stochastic", 2)])
def test_a_frames_shadow_maps_are_handed_to_the_next_frame_without_a_full_collection(method, samples):
    """The frame context sits in reference cycles; Renderer.render releases its caches, so the
    next frame lays its maps out in the same memory instead of faulting in new (50 MB on demo).
    Accumulation at 16 instants shares maps of 8 instants, held by the context for the frame."""
    import warp_blur as wb
    gc.collect()
    reuse.clear()
    r = wb.Renderer("usd_scenes/demo.usda", resolution=(32, 24),
                    settings=wb.RenderSettings(aovs=(), method=method, samples=samples))
    kept = []
    gc.disable()   # the cycle collector must not be what frees a frame
    try:
        for _ in range(3):
            r.render(12)
            kept.append({a.ptr for k, a in reuse._kept if 512 in k[0]})
    finally:
        gc.enable()
        reuse.clear()
    assert kept[0] and kept[0] == kept[1] == kept[2]   # handed back after each frame, and reused

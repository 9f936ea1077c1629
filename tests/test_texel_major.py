"""Maps laid out face by face while they render (shadows/texel_major.py) equal the whole frame's
layout done afterwards (device_data.face_slots) and its varying-texel flags."""

from __future__ import annotations

import numpy as np
import pytest

from warp_blur.raster.device_data import face_slots
from warp_blur.shadows.layout import ShadowData
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


@pytest.mark.parametrize("seed", [0, 1])
def test_faces_laid_out_in_any_order_equal_the_whole_layout(seed):
    maps, lights = frame_maps(seed)
    expected, _faces, expected_varying, _lights = face_slots(
        ShadowData(maps, np.zeros((len(maps), 19), np.float32), lights, B, S))
    laid = TexelMajorLayout(maps, B)
    for first, m, f in lights:
        laid.add_light(int(first), int(m), int(f))
    # every instant of the second light's last face (slot 4), and a random third of the rest,
    # reported in a random order
    rng = np.random.default_rng(seed)
    last_face = [8 + b * 3 + 2 for b in range(B)]
    others = [i for i in rng.permutation(len(maps)) if i not in last_face][: len(maps) // 3]
    for idx in rng.permutation(last_face + others):
        laid.rendered(int(idx))
    # a face whose B instants were all reported is laid out already, before finish()
    done = [slot for slot in range(expected.shape[0]) if laid.laid_out(slot)]
    assert 4 in done
    for slot in done:
        np.testing.assert_array_equal(laid.slots[slot], expected[slot])
        np.testing.assert_array_equal(laid.varying[slot], expected_varying[slot])
    laid.finish()
    np.testing.assert_array_equal(laid.slots, expected)
    np.testing.assert_array_equal(laid.varying, expected_varying)
    assert 0.0 < laid.varying.mean() < 0.5


def test_a_map_of_no_registered_light_is_an_error():
    maps, lights = frame_maps(0)
    laid = TexelMajorLayout(maps, B)
    laid.add_light(0, 2, 1)
    with pytest.raises(IndexError):
        laid.rendered(len(maps) - 1)

"""The time-continuous kernels' layout of a frame's maps, built while the maps render.

Stochastic and analytic read each texel's B map instants side by side, (slots, S, S, B) float32
(device_data.face_slots). Transposing all of a frame's maps into that layout after the last one
is rendered is a copy limited by memory bandwidth (about 25 ms for demo's 48 maps of 512²) with
one core idle. Here each face is laid out, with its varying-texel flags, by the thread that
renders its last instant, while the other threads render other faces.
"""

from __future__ import annotations

import threading

import numpy as np
import warp as wp

from . import layout


class TexelMajorLayout:
    """Maps (N, S, S) of B instants each (map first + (m B + b) F + f: light sample m, instant b,
    face f of a light whose maps start at `first`) laid out as slots (slots, S, S, B), slot
    first / B + m F + f, and flags (slots, S, S) uint8: 1 where a texel's depth is not the same in
    all B instants (layout.face_varying)."""

    def __init__(self, maps: np.ndarray, times: int) -> None:
        self.maps, self.times = maps, times
        s = maps.shape[1]
        slots = maps.shape[0] // times
        # on the CPU the kernels read this array itself (no upload, no second copy); another
        # device gets a copy (device_data.make_shading)
        self.array = wp.empty((max(slots, 1), s, s, times), dtype=float, device="cpu")
        self.slots = self.array.numpy()
        self.varying_array = wp.zeros((max(slots, 1), s, s), dtype=wp.uint8, device="cpu")
        self.varying = self.varying_array.numpy()
        self._lights: list[tuple[int, int, int]] = []   # (first map, samples M, faces F)
        self._remaining = np.full(max(slots, 1), times, np.int64)
        self._laid = np.zeros(max(slots, 1), bool)
        self._lock = threading.Lock()

    def add_light(self, first: int, samples: int, faces: int) -> None:
        """Register a light whose M samples × B instants × F faces of maps start at `first`."""
        self._lights.append((first, samples, faces))

    def laid_out(self, slot: int) -> bool:
        """True once slot's face is laid out (with its flags)."""
        return bool(self._laid[slot])

    def _slot_of(self, idx: int) -> tuple[int, int, int]:
        """(slot, first map of its light, faces F) of map idx."""
        b = self.times
        for first, samples, faces in self._lights:
            if first <= idx < first + samples * b * faces:
                rel = idx - first
                return first // b + (rel // (b * faces)) * faces + rel % faces, first, faces
        raise IndexError(f"map {idx} belongs to no registered light")

    def rendered(self, idx: int) -> None:
        """Map idx is complete: lay its face out once all B of the face's instants are."""
        slot, first, faces = self._slot_of(idx)
        with self._lock:
            self._remaining[slot] -= 1
            ready = self._remaining[slot] == 0 and not self._laid[slot]
            if ready:
                self._laid[slot] = True
        if ready:
            self._lay(slot, first, faces)

    def finish(self) -> None:
        """Lay out every face not laid out yet (the maps are all rendered by now)."""
        b = self.times
        for first, samples, faces in self._lights:
            for slot in range(first // b, first // b + samples * faces):
                with self._lock:
                    todo = not self._laid[slot]
                    self._laid[slot] = True
                if todo:
                    self._lay(slot, first, faces)

    def _lay(self, slot: int, first: int, faces: int) -> None:
        b = self.times
        local = slot - first // b
        m, f = divmod(local, faces)
        start = first + m * b * faces + f
        stack = self.maps[start:start + b * faces:faces]          # (B, S, S): this face's instants
        self.slots[slot] = stack.transpose(1, 2, 0)
        self.varying[slot] = layout.face_varying(stack)

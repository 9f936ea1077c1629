"""The time-continuous kernels' layout of a frame's maps, rendered into directly.

Stochastic and analytic read each texel's B map instants side by side, (slots, S, S, B) float32
(device_data.face_slots). A face's direct maps are splatted straight into that layout, all B
instants in one pass (FaceRasterizer.splat_instants); a map made one at a time (warped) is
written into its instant's place. Nothing is laid out twice: no
frame-sized instant-major copy, no transpose after the maps render.
"""

from __future__ import annotations

import threading

import numpy as np
import warp as wp

from ..core.reuse import reused_empty
from ..kernels.shadow_raster import flag_varying_texels
from . import free_entries


class TexelMajorLayout:
    """Maps of B instants each (map first + (m B + b) F + f: light sample m, instant b, face f of a
    light whose maps start at `first`) held as slots (slots, S, S, B), slot first / B + m F + f,
    and flags (slots, S, S) uint8: 1 where a texel's depth may not be the same in all B instants
    (layout.face_varying's, exact from flag(); from done(), conservatively where a triangle drew),
    and occupancy (slots, G, G) uint8, G = ceil(S / block): 1 at the block² texel blocks that hold
    a depth (not +inf) at some instant, marked as the maps are written (fill, put, and the splat
    into occupied_slot), so free_entries.occupancy_table need not read the maps again."""

    def __init__(self, slots: int, size: int, times: int) -> None:
        self.times, self.size = times, size
        # on the CPU the kernels read this array itself (no upload, no second copy); another
        # device gets a copy (device_data.make_shading)
        # last frame's memory when the shape is the same (core/reuse.py): every instant of every
        # slot is written before it is read
        self.array = reused_empty((max(slots, 1), size, size, times), float)
        self.slots = self.array.numpy()
        self.varying_array = wp.zeros((max(slots, 1), size, size), dtype=wp.uint8, device="cpu")
        self.varying = self.varying_array.numpy()
        self._lights: list[tuple[int, int, int]] = []   # (first map, samples M, faces F)
        self._flagged = np.zeros(max(slots, 1), bool)
        self.block = free_entries.BLOCK   # (read now: tests change it)
        g = -(-size // self.block)
        self.occupancy_array = wp.zeros((max(slots, 1), g, g), dtype=wp.uint8, device="cpu")
        self.occupancy = self.occupancy_array.numpy()
        #: False once a slot was splatted on another device (its blocks are then not marked here)
        self.occupancy_complete = True
        self._marking = threading.Lock()   # faces render on several threads

    def add_light(self, first: int, samples: int, faces: int) -> None:
        """Register a light whose M samples × B instants × F faces of maps start at `first`."""
        self._lights.append((first, samples, faces))

    def locate(self, idx: int) -> tuple[int, int]:
        """(slot, instant b) of map idx."""
        b = self.times
        for first, samples, faces in self._lights:
            if first <= idx < first + samples * b * faces:
                rel = idx - first
                return first // b + (rel // (b * faces)) * faces + rel % faces, (rel // faces) % b
        raise IndexError(f"map {idx} belongs to no registered light")

    def put(self, idx: int, depth: np.ndarray) -> None:
        """Map idx (S, S) made on its own: written into its slot at its instant."""
        slot, b = self.locate(idx)
        self.slots[slot][..., b] = depth
        self.mark(slot, depth)

    def fill(self, slot: int, instants: list[int], depth: np.ndarray | None) -> None:
        """Instants of a slot set to one map (S, S) (None: empty, inf)."""
        block = self.slots[slot]
        which = sorted(set(instants))
        if len(which) == self.times:
            if depth is None:
                block.fill(np.inf)
            else:
                np.copyto(block, depth[..., None])
        else:
            block[..., which] = np.inf if depth is None else depth[..., None]
        if depth is not None:
            self.mark(slot, depth)

    def mark(self, slot: int, depth: np.ndarray) -> None:
        """Mark the blocks of a map (S, S) written into the slot that hold anything but +inf."""
        g, b = self.occupancy.shape[1], self.block
        held = np.zeros((g * b, g * b), bool)
        held[:self.size, :self.size] = ~(depth == np.inf)   # a depth, or a NaN: occupied
        blocks = held.reshape(g, b, g, b).any(axis=(1, 3))
        with self._marking:
            self.occupancy[slot] |= blocks

    def occupied_slot(self, slot: int, device: str) -> wp.array | None:
        """The slot's occupancy blocks (G * G,) uint8 for splat_shadow_depth on `device`: the
        CPU's own memory; None elsewhere (the occupancy is then found by reading the maps)."""
        if not wp.get_device(device).is_cpu:
            self.occupancy_complete = False
            return None
        n = self.occupancy.shape[1] * self.occupancy.shape[2]
        view = wp.array(ptr=self.occupancy_array.ptr + slot * n, shape=(n,), dtype=wp.uint8, device="cpu")
        view.owner_array = self.occupancy_array
        return view

    def target(self, slot: int, device: str) -> wp.array:
        """The slot as a (S * S * B,) array on `device` to render into: on the CPU the slot's own
        memory; elsewhere a copy, brought back by done()."""
        if wp.get_device(device).is_cpu:
            n = self.size * self.size * self.times
            view = wp.array(ptr=self.array.ptr + slot * n * 4, shape=(n,), dtype=float, device="cpu")
            view.owner_array = self.array   # a view from a pointer does not keep its memory alive
            return view
        return wp.array(self.slots[slot].ravel(), dtype=float, device=device)

    def flags(self, slot: int, device: str) -> wp.array:
        """The slot's varying flags (S * S,) uint8 on `device` (zero until set): the CPU's own
        memory, or a zeroed array elsewhere, brought back by done()."""
        n = self.size * self.size
        if wp.get_device(device).is_cpu:
            view = wp.array(ptr=self.varying_array.ptr + slot * n, shape=(n,), dtype=wp.uint8, device="cpu")
            view.owner_array = self.varying_array
            return view
        return wp.zeros(n, dtype=wp.uint8, device=device)

    def done(self, slot: int, target: wp.array, touched: wp.array) -> None:
        """The slot was filled with one base at all B instants and splatted into (target) with its
        touched texels flagged (touched): those flags are its varying flags, exact where the base is
        and conservative where a triangle drew behind it. Copied back from another device."""
        if not target.device.is_cpu:
            self.slots[slot] = target.numpy().reshape(self.slots[slot].shape)
            if touched.shape[0] > 0:
                self.varying[slot] = touched.numpy().reshape(self.varying[slot].shape)
        self._flagged[slot] = touched.shape[0] > 0   # else flag() compares the instants

    def settle(self, slot: int, whole: bool) -> None:
        """Flags of a slot that holds what fill() put there: no texel varies when the fill covered
        every instant (whole), else its instants are compared (flag)."""
        if not whole:
            self.flag(slot)
            return
        self.varying[slot] = 0
        self._flagged[slot] = True

    def flag(self, slot: int) -> None:
        """Set the slot's varying-texel flags by comparing its B instants (all in place)."""
        wp.launch(flag_varying_texels, dim=self.size, inputs=[self.target(slot, "cpu"), self.size, self.times],
                  outputs=[self.flags(slot, "cpu")], device="cpu")
        self._flagged[slot] = True

    def finish(self) -> None:
        """Flag every slot not flagged yet (every map is in place by now)."""
        for slot in np.flatnonzero(~self._flagged):
            self.flag(int(slot))

    def instant_maps(self) -> np.ndarray:
        """(N, S, S) copy of the maps in map order (instant-major), for readers of single images."""
        b, s = self.times, self.size
        n = sum(m * b * f for _first, m, f in self._lights)
        out = np.empty((n, s, s), np.float32)
        for first, m, f in self._lights:
            block = self.slots[first // b:first // b + m * f].reshape(m, f, s, s, b)
            out[first:first + m * b * f] = block.transpose(0, 4, 1, 2, 3).reshape(m * b * f, s, s)
        return out

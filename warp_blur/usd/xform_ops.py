"""Local-to-world transforms of many moving prims at many shutter times, batched in NumPy: what
UsdGeom.XformCache gives prim by prim (~8 µs a prim and time: 3000 animated props cost an
accumulation frame's 76 snapshots 1.9 s).

Between two authored samples USD interpolates each op's value linearly. So over a frame's window
[lo, hi], an op's value at any time is the interpolation of its values at the window's breakpoints
(its ends and every sample time inside it), read from USD once a frame. The op matrices are then
built and multiplied for every prim of an op-stack signature at once (row vectors, the last op of
xformOpOrder on the left, as UsdGeom.Xformable composes them; the ops of animated ancestors above
the prim's), under the world transform of the nearest ancestor that holds still. What this does
not follow is left to USD (`LinearTransforms.placed` says which prims it places): held
interpolation, splines, an inverted scale or matrix, an op that does not read, more than
MAX_BREAKPOINTS samples in the window, and `orient` ops, which USD slerps (linearly where two
quaternions are within 1e-5 of parallel, leaving them off unit length) and turns into a rotation
from the quaternion as it stands: near the identity a length off by 2e-6 turns a glTF asset's cube
by 2e-3 rad, which normalising here would not reproduce. Values of float-precision ops
interpolate in float64 here and in float32 in USD: agreement to ~1e-7 relative there, ~1e-12 for
double ops."""

from __future__ import annotations

import numpy as np
from pxr import Gf, Usd, UsdGeom

from .stage import transform_may_vary

_T = UsdGeom.XformOp
_AXES = {"X": 0, "Y": 1, "Z": 2}
_ROTATE3 = {_T.TypeRotateXYZ: "XYZ", _T.TypeRotateXZY: "XZY", _T.TypeRotateYXZ: "YXZ",
            _T.TypeRotateYZX: "YZX", _T.TypeRotateZXY: "ZXY", _T.TypeRotateZYX: "ZYX"}
_ROTATE1 = {_T.TypeRotateX: 0, _T.TypeRotateY: 1, _T.TypeRotateZ: 2}
_TRANSLATE1 = {_T.TypeTranslateX: 0, _T.TypeTranslateY: 1, _T.TypeTranslateZ: 2}
_SCALE1 = {_T.TypeScaleX: 0, _T.TypeScaleY: 1, _T.TypeScaleZ: 2}
_SPLINES = hasattr(Usd.Attribute, "HasSpline")   # USD 24.11 on: a scalar op may hold a spline
_SUPPORTED = ({_T.TypeTranslate, _T.TypeScale, _T.TypeTransform} | set(_ROTATE3) | set(_ROTATE1)
              | set(_TRANSLATE1) | set(_SCALE1))


def op_structure(prim: Usd.Prim, parent_to_world, memo: dict) -> tuple | None:
    """(signature ((op type, inverse), ...), attributes, (4, 4) base-to-world) of the ops that move a prim,
    its own and its animated ancestors' (a gprim under an animated Xform), top first; the base is
    the world transform of the nearest ancestor that holds still (parent_to_world(ancestor)), or
    the identity at the root or a resetXformStack. None where an op is of a kind not handled here,
    holds a spline, or inverts a scale or matrix (it may be singular: USD's own answer). What
    does not change from frame to frame: kept with the prim's unit. memo: transform_may_vary's."""
    chain = []
    p = prim
    for _depth in range(64):
        xformable = UsdGeom.Xformable(p)
        chain.append(xformable.GetOrderedXformOps() if xformable else [])
        parent = p.GetParent()
        if (xformable and xformable.GetResetXformStack()) or not parent or parent.IsPseudoRoot():
            base = np.eye(4)
            break
        if not transform_may_vary(parent, memo):
            base = parent_to_world(parent)
            break
        p = parent
    else:
        return None
    signature, ops = [], []
    for op in (op for level in reversed(chain) for op in level):
        kind, inverse = op.GetOpType(), bool(op.IsInverseOp())
        if kind not in _SUPPORTED or (_SPLINES and op.GetAttr().HasSpline()):
            return None
        if inverse and (kind == _T.TypeTransform or kind == _T.TypeScale or kind in _SCALE1):
            return None
        signature.append((kind, inverse))
        ops.append(op.GetAttr())
    return (tuple(signature), ops, base) if ops else None


def _interior_samples(attrs: list, lo: float, hi: float) -> list[float]:
    """The attributes' authored sample times strictly inside (lo, hi): where their values bend."""
    times = []
    for attr in attrs:
        if attr.ValueMightBeTimeVarying():
            times.extend(t for t in attr.GetTimeSamplesInInterval(Gf.Interval(lo, hi)) if lo < t < hi)
    return times


def _op_size(kind) -> int:
    return 16 if kind == _T.TypeTransform else 1 if kind in _ROTATE1 or kind in _TRANSLATE1 or kind in _SCALE1 else 3


def _values_array(raw: list, shape: tuple) -> np.ndarray:
    """raw USD values (Gf vectors, matrices, floats, None) as a float64 array of `shape`
    ((K, B, n)), NaN where one does not read or is not of the op's size: one NumPy call (their
    buffers) where all read alike, else value by value."""
    if all(v is not None for v in raw):
        try:
            return np.array(raw, np.float64).reshape(shape)
        except (TypeError, ValueError):
            pass
    rows = []
    for v in raw:
        x = None
        if v is not None:
            try:
                x = np.asarray(v, np.float64).reshape(-1)
            except (TypeError, ValueError):
                x = None
        rows.append(x if x is not None and x.size == shape[-1] else np.full(shape[-1], np.nan))
    return np.stack(rows).reshape(shape)


def _axis_rotations(axis: int, degrees: np.ndarray) -> np.ndarray:
    """(K, 4, 4) row-vector rotations by `degrees` (K,) about axis 0, 1 or 2 (right-handed)."""
    r = np.radians(degrees)
    c, s = np.cos(r), np.sin(r)
    m = np.zeros((len(r), 4, 4))
    m[:, 3, 3] = 1.0
    i, j = [(1, 2), (2, 0), (0, 1)][axis]
    m[:, axis, axis] = 1.0
    m[:, i, i] = c
    m[:, i, j] = s
    m[:, j, i] = -s
    m[:, j, j] = c
    return m


def _op_matrices(kind, lo: np.ndarray, hi: np.ndarray, a: float) -> np.ndarray:
    """(K, 4, 4) matrices of K ops of one kind at a fraction a of the window (values lo, hi (K, n))."""
    k = len(lo)
    v = lo + (hi - lo) * a
    if kind == _T.TypeTransform:
        return v.reshape(k, 4, 4).copy()
    m = np.zeros((k, 4, 4))
    m[:, [0, 1, 2, 3], [0, 1, 2, 3]] = 1.0
    if kind == _T.TypeTranslate:
        m[:, 3, :3] = v
    elif kind in _TRANSLATE1:
        m[:, 3, _TRANSLATE1[kind]] = v[:, 0]
    elif kind == _T.TypeScale:
        m[:, [0, 1, 2], [0, 1, 2]] = v
    elif kind in _SCALE1:
        m[:, _SCALE1[kind], _SCALE1[kind]] = v[:, 0]
    elif kind in _ROTATE1:
        m = _axis_rotations(_ROTATE1[kind], v[:, 0])
    else:   # rotateABC: about A first, then B, then C (row vectors: R_A R_B R_C)
        order = _ROTATE3[kind]
        m = _axis_rotations(_AXES[order[0]], v[:, _AXES[order[0]]])
        for axis_name in order[1:]:
            m = m @ _axis_rotations(_AXES[axis_name], v[:, _AXES[axis_name]])
    return m


#: most sample times inside a frame's window the batch follows (baked animation with a sample
#: a frame and a shutter under a frame has one or two)
MAX_BREAKPOINTS = 16


class LinearTransforms:
    """Local-to-world transforms over a window [lo, hi] of those of `prims` that op_structure
    handles: every op's values read at the window's breakpoints (its ends and the samples inside
    it), linear between them; one NumPy pass per op-stack signature.
    holders[i] (any object, e.g. the prim's transforms_at) keeps prim i's op_structure across
    frames; None to find it again."""

    def __init__(self, prims: list[Usd.Prim], lo: float, hi: float, memo: dict, parent_cache: UsdGeom.XformCache,
                 holders: list | None = None):
        self.lo, self.hi = float(min(lo, hi)), float(max(lo, hi))
        self.placed = np.zeros(len(prims), bool)
        self.batches = []
        if not prims or prims[0].GetStage().GetInterpolationType() != Usd.InterpolationTypeLinear:
            return
        parents: dict = {}

        def parent_to_world(parent: Usd.Prim) -> np.ndarray:
            key = parent.GetPath()
            if key not in parents:
                parents[key] = np.array(parent_cache.GetLocalToWorldTransform(parent), np.float64)
            return parents[key]

        structures = []
        for i, prim in enumerate(prims):
            holder = holders[i] if holders is not None else None
            structure = getattr(holder, "xform_structure", False)
            if structure is False:
                structure = op_structure(prim, parent_to_world, memo)
                if holder is not None:
                    holder.xform_structure = structure
            structures.append(structure)
        inside = sorted({t for st in structures if st is not None for t in _interior_samples(st[1], self.lo, self.hi)})
        if len(inside) > MAX_BREAKPOINTS:
            return
        self.breakpoints = np.array([self.lo] + inside + ([self.hi] if self.hi > self.lo else []), np.float64)
        by_signature: dict = {}
        for i, st in enumerate(structures):
            if st is not None:
                by_signature.setdefault(st[0], []).append((i, st[1], st[2]))
        # per signature: (members (K,), per op (K, B, n) values at the breakpoints, (K, 4, 4) bases)
        times = [float(t) for t in self.breakpoints]
        for signature, rows in by_signature.items():
            values = [_values_array([attrs[j].Get(t) for _, attrs, _ in rows for t in times],
                                    (len(rows), len(times), _op_size(kind)))
                      for j, (kind, _) in enumerate(signature)]
            ok = np.logical_and.reduce([np.isfinite(v).all(axis=(1, 2)) for v in values])
            if not ok.any():
                continue
            members = np.array([i for i, _, _ in rows])[ok]
            self.placed[members] = True
            self.batches.append((signature, members, [v[ok] for v in values],
                                 np.stack([b for _, _, b in rows])[ok]))

    def covers(self, time: float) -> bool:
        return self.lo <= time <= self.hi and bool(self.placed.any())

    def at(self, time: float, out: np.ndarray) -> None:
        """Write the (4, 4) local-to-world at USD time `time` (inside the window) of every placed
        prim into out (len(prims), 4, 4); the other rows are left as they are."""
        bp = self.breakpoints
        j = min(max(int(np.searchsorted(bp, time, side="right")) - 1, 0), max(len(bp) - 2, 0))
        a = 0.0 if len(bp) < 2 else (time - bp[j]) / (bp[j + 1] - bp[j])
        k = min(j + 1, len(bp) - 1)
        for signature, members, values, bases in self.batches:
            local = None
            for (kind, inverse), v in zip(signature, values):
                m = _op_matrices(kind, v[:, j], v[:, k], a)
                if inverse:
                    m = np.linalg.inv(m)
                local = m if local is None else m @ local   # later ops act on the point first: left
            out[members] = local @ bases

"""Local-to-world transforms of many moving prims at many shutter times, batched in NumPy: what
UsdGeom.XformCache gives prim by prim (~8 µs a prim and time: 3000 animated props cost an
accumulation frame's 76 snapshots 1.9 s), for the prims whose xformOps are all linear in time over
the frame's window.

Between two authored samples USD interpolates each op's value linearly (an `orient` quaternion by
slerp), so where no sample lies strictly inside the window [lo, hi], each op's value at a time in it
is the interpolation of its values at lo and hi, read from USD once a frame. The op matrices are
then built and multiplied for every such prim of an op-stack signature at once (row vectors, the
last op of xformOpOrder on the left, as UsdGeom.Xformable composes them; the ops of animated
ancestors above the prim's), under the world transform of the nearest ancestor that holds still.
Anything else (held interpolation, splines, a sample inside the window, an op that does not read)
is left to USD: `LinearTransforms.placed` says which prims it places. Values of float-precision
ops interpolate in float64 here and in float32 in USD: agreement to ~1e-7 relative there, ~1e-12
for double ops."""

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
_SUPPORTED = ({_T.TypeTranslate, _T.TypeScale, _T.TypeOrient, _T.TypeTransform} | set(_ROTATE3) | set(_ROTATE1)
              | set(_TRANSLATE1) | set(_SCALE1))


def _value(op: UsdGeom.XformOp, time: float) -> np.ndarray | None:
    """The op's value at a time as a flat float64 array (a quaternion as w, x, y, z; a matrix by
    rows), or None when it does not read."""
    v = op.Get(Usd.TimeCode(time))
    if v is None:
        return None
    if isinstance(v, (Gf.Quatd, Gf.Quatf, Gf.Quath)):
        im = v.GetImaginary()
        return np.array([v.GetReal(), im[0], im[1], im[2]], np.float64)
    try:
        return np.asarray(v, np.float64).reshape(-1)
    except (TypeError, ValueError):
        return None


def _op_linear(op: UsdGeom.XformOp, lo: float, hi: float) -> bool:
    """True when the op's value is USD's linear (or slerp) interpolation of its values at lo and hi
    over [lo, hi]: no spline, and no time sample strictly inside."""
    attr = op.GetAttr()
    if _SPLINES and attr.HasSpline():
        return False
    if not attr.ValueMightBeTimeVarying():
        return True
    return all(not (lo < s < hi) for s in attr.GetTimeSamplesInInterval(Gf.Interval(lo, hi)))


def linear_stack(prim: Usd.Prim, lo: float, hi: float, parent_to_world, memo: dict) -> tuple | None:
    """(signature, values at lo, values at hi, (4, 4) base-to-world) of a prim whose transform is a
    product of ops linear over [lo, hi] under a held one, or None (USD places it). The ops are the
    prim's and its animated ancestors' (a gprim under an animated Xform), top first; the base is the
    world transform of the nearest ancestor that holds still (parent_to_world(ancestor)), or the
    identity at the root or a resetXformStack. memo: transform_may_vary's verdicts."""
    if prim.GetStage().GetInterpolationType() != Usd.InterpolationTypeLinear:
        return None
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
    signature, v_lo, v_hi = [], [], []
    for op in (op for ops in reversed(chain) for op in ops):
        kind = op.GetOpType()
        if kind not in _SUPPORTED or not _op_linear(op, lo, hi):
            return None
        a, b = _value(op, lo), _value(op, hi)
        if a is None or b is None or a.shape != b.shape or not (np.isfinite(a).all() and np.isfinite(b).all()):
            return None
        expected = 16 if kind == _T.TypeTransform else 4 if kind == _T.TypeOrient else \
            1 if kind in _ROTATE1 or kind in _TRANSLATE1 or kind in _SCALE1 else 3
        if a.size != expected:
            return None
        inverse = bool(op.IsInverseOp())
        if inverse and (kind == _T.TypeTransform or kind == _T.TypeScale or kind in _SCALE1):
            return None   # may be singular: USD's own answer
        signature.append((kind, inverse))
        v_lo.append(a)
        v_hi.append(b)
    if not signature:
        return None
    return tuple(signature), v_lo, v_hi, base


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


def _slerp(q0: np.ndarray, q1: np.ndarray, a: float) -> np.ndarray:
    """(K, 4) unit quaternions (w, x, y, z) a of the way from q0 to q1 (K, 4) along the shorter
    arc, as GfSlerp."""
    q0 = q0 / np.linalg.norm(q0, axis=1, keepdims=True)
    q1 = q1 / np.linalg.norm(q1, axis=1, keepdims=True)
    dot = np.sum(q0 * q1, axis=1)
    q1 = np.where(dot[:, None] < 0.0, -q1, q1)
    dot = np.abs(dot)
    theta = np.arccos(np.clip(dot, -1.0, 1.0))
    sin_t = np.sin(theta)
    near = sin_t < 1e-6
    safe = np.where(near, 1.0, sin_t)
    w0 = np.where(near, 1.0 - a, np.sin((1.0 - a) * theta) / safe)
    w1 = np.where(near, a, np.sin(a * theta) / safe)
    q = w0[:, None] * q0 + w1[:, None] * q1
    return q / np.linalg.norm(q, axis=1, keepdims=True)


def _quat_matrices(q: np.ndarray) -> np.ndarray:
    """(K, 4, 4) row-vector rotations of unit quaternions (K, 4) (w, x, y, z)."""
    w, x, y, z = q.T
    m = np.zeros((len(q), 4, 4))
    m[:, 0, 0] = 1 - 2 * (y * y + z * z)
    m[:, 0, 1] = 2 * (x * y + w * z)
    m[:, 0, 2] = 2 * (x * z - w * y)
    m[:, 1, 0] = 2 * (x * y - w * z)
    m[:, 1, 1] = 1 - 2 * (x * x + z * z)
    m[:, 1, 2] = 2 * (y * z + w * x)
    m[:, 2, 0] = 2 * (x * z + w * y)
    m[:, 2, 1] = 2 * (y * z - w * x)
    m[:, 2, 2] = 1 - 2 * (x * x + y * y)
    m[:, 3, 3] = 1.0
    return m


def _op_matrices(kind, lo: np.ndarray, hi: np.ndarray, a: float) -> np.ndarray:
    """(K, 4, 4) matrices of K ops of one kind at a fraction a of the window (values lo, hi (K, n))."""
    k = len(lo)
    if kind == _T.TypeOrient:
        return _quat_matrices(_slerp(lo, hi, a))
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


class LinearTransforms:
    """Local-to-world transforms over a window [lo, hi] of those of `prims` whose op stacks are
    linear there (linear_stack), one NumPy pass per op-stack signature for all of them."""

    def __init__(self, prims: list[Usd.Prim], lo: float, hi: float, memo: dict, parent_cache: UsdGeom.XformCache):
        self.lo, self.hi = float(min(lo, hi)), float(max(lo, hi))
        parents: dict = {}

        def parent_to_world(parent: Usd.Prim) -> np.ndarray:
            key = parent.GetPath()
            if key not in parents:
                parents[key] = np.array(parent_cache.GetLocalToWorldTransform(parent), np.float64)
            return parents[key]

        self.placed = np.zeros(len(prims), bool)
        by_signature: dict = {}
        for i, prim in enumerate(prims):
            stack = linear_stack(prim, self.lo, self.hi, parent_to_world, memo)
            if stack is not None:
                self.placed[i] = True
                by_signature.setdefault(stack[0], []).append((i, stack))
        # per signature: (members (K,), per op (K, n) values at lo and hi, (K, 4, 4) parents)
        self.batches = []
        for signature, rows in by_signature.items():
            members = np.array([i for i, _ in rows])
            lows = [np.stack([s[1][j] for _, s in rows]) for j in range(len(signature))]
            highs = [np.stack([s[2][j] for _, s in rows]) for j in range(len(signature))]
            self.batches.append((signature, members, lows, highs, np.stack([s[3] for _, s in rows])))

    def covers(self, time: float) -> bool:
        return self.lo <= time <= self.hi and bool(self.placed.any())

    def at(self, time: float, out: np.ndarray) -> None:
        """Write the (4, 4) local-to-world at USD time `time` (inside the window) of every placed
        prim into out (len(prims), 4, 4); the other rows are left as they are."""
        a = 0.0 if self.hi == self.lo else (time - self.lo) / (self.hi - self.lo)
        for signature, members, lows, highs, parents in self.batches:
            local = None
            for (kind, inverse), lo, hi in zip(signature, lows, highs):
                m = _op_matrices(kind, lo, hi, a)
                if inverse:
                    m = np.linalg.inv(m)
                local = m if local is None else m @ local   # later ops act on the point first: left
            out[members] = local @ parents

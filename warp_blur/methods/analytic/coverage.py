"""When a linearly moving triangle covers a pixel ray: the exact coverage pieces of its span.

Each edge function at the ray, e(s) = d · ((a(s)-o) × (b(s)-o)), is a quadratic in the span's time
s ∈ [0, 1]. Its roots split the span into pieces of constant sign; a piece is covered where all
three edge functions share a sign (either orientation: back faces and orientation flips are
allowed, and a rotating triangle may cover a pixel in several disjoint pieces).

Every function here is generic over the float type (float32 vectors in the renderer's kernels,
float64 in `coverage_times`), so the precision report runs the renderer's own coverage code in
both precisions and compares (bench/precision_report.py).
"""

from __future__ import annotations

from typing import Any

import warp as wp

from ...kernels.kernel_types import Geometry, View
from ...kernels.rays import edge_cross, edge_owns

#: coverage breakpoints per span: up to two roots for each of three edges, so at most 7 pieces
MAX_SPAN_PIECES = wp.constant(7)
#: an edge function whose coefficients are all below this × their scale is zero up to rounding
DEGENERATE_TOL_F32 = wp.constant(4.0e-7)
DEGENERATE_TOL_F64 = 1.0e-15


@wp.func
def edge_vectors(a0: Any, da: Any, b0: Any, db: Any, ia: int, ib: int):
    """(P, Q, R) with e(s) = d·P + s d·Q + s² d·R for the edge from a(s) = a0 + s da to b(s)
    (eye-relative), in the canonical form of `edge_cross`: base × (other − base) from the
    lower-index vertex, exactly antisymmetric between the triangles sharing the edge (the sign is
    folded in, which is exact)."""
    sign = type(a0[0])(1.0)
    p0 = a0
    dp = da
    q0 = b0
    dq = db
    if ia > ib:
        sign = type(a0[0])(-1.0)
        p0 = b0
        dp = db
        q0 = a0
        dq = da
    e0 = q0 - p0
    de = dq - dp
    return sign * wp.cross(p0, e0), sign * (wp.cross(p0, de) + wp.cross(dp, e0)), sign * wp.cross(dp, de)


@wp.func
def edge_coeffs(d: Any, a0: Any, da: Any, b0: Any, db: Any, ia: int, ib: int):
    """(c0, c1, c2) of e(s) = c0 + c1 s + c2 s² for the edge from a(s) = a0 + s da to b(s) at ray d
    (edge_vectors)."""
    p, q, r = edge_vectors(a0, da, b0, db, ia, ib)
    return type(d)(wp.dot(d, p), wp.dot(d, q), wp.dot(d, r))


@wp.func
def eval_quad(c: Any, s: Any):
    return c[0] + s * (c[1] + s * c[2])


@wp.func
def quad_roots(c: Any):
    """Roots of c0 + c1 s + c2 s² inside (0, 1), in any order; 2 marks a missing root.

    Uses the cancellation-free form q = -(c1 + sign(c1) sqrt(disc)) / 2, roots q/c2 and c0/q."""
    zero = type(c[0])(0.0)
    one = type(c[0])(1.0)
    two = type(c[0])(2.0)
    r0 = two
    r1 = two
    c0 = c[0]
    c1 = c[1]
    c2 = c[2]
    if c2 == zero:
        if c1 != zero:
            r0 = -c0 / c1
    else:
        disc = c1 * c1 - type(c[0])(4.0) * c2 * c0
        if disc >= zero:
            sq = wp.sqrt(disc)
            sgn = one
            if c1 < zero:
                sgn = -one
            q = type(c[0])(-0.5) * (c1 + sgn * sq)
            r0 = q / c2
            if q != zero:
                r1 = c0 / q
    if not (r0 > zero and r0 < one):
        r0 = two
    if not (r1 > zero and r1 < one):
        r1 = two
    return wp.vector(r0, r1)


@wp.func
def edge_degenerate(coef: Any, d: Any, a0: Any, da: Any, b0: Any, db: Any, tol: Any) -> int:
    """1 when the edge function is zero up to rounding (tol × its scale) over the whole span: the
    ray lies in the plane of the edge and the eye at all times (e.g. a pixel on an edge whose
    plane holds the camera's whole dolly path)."""
    big = wp.max(wp.max(wp.abs(coef[0]), wp.abs(coef[1])), wp.abs(coef[2]))
    # cheap first: (x + y)² <= 2 (x² + y²) bounds the squared scale without square roots
    e0 = b0 - a0
    de = db - da
    two = type(tol)(2.0)
    bound2 = wp.dot(d, d) * two * (wp.dot(a0, a0) + wp.dot(da, da)) * two * (wp.dot(e0, e0) + wp.dot(de, de))
    if big * big > tol * tol * bound2:
        return 0
    scale = wp.length(d) * (wp.length(a0) + wp.length(da)) * (wp.length(e0) + wp.length(de))
    if big <= tol * scale:
        return 1
    return 0


@wp.func
def edge_sides(coef: Any, degenerate: int, s: Any, p: Any, q: Any, ip: int, iq: int):
    """(positive side ok, negative side ok) of the edge from vertex ip (eye-relative position p at
    time s) to iq (q) at time s, as 1/0.

    A degenerate edge (see edge_degenerate) or an exact zero is a tie, settled by the same
    ownership rule as the sharp test on the edge's canonical cross vector (`edge_cross`, computed
    only then), so two triangles sharing the edge cover the pixel once."""
    zero = type(s)(0.0)
    one = type(s)(1.0)
    val = eval_quad(coef, s)
    pos = zero
    neg = zero
    if degenerate != 0 or val == zero:
        c = edge_cross(p, q, ip, iq)
        if edge_owns(c):
            pos = one
        if edge_owns(-c):
            neg = one
    elif val > zero:
        pos = one
    else:
        neg = one
    return wp.vector(pos, neg)


@wp.func
def next_breakpoint(ra: Any, rb: Any, rc: Any, s_prev: Any):
    """The smallest edge root after s_prev (1 when none): the next time a coverage sign may change."""
    s_next = type(s_prev)(1.0)
    for r in range(2):
        if ra[r] > s_prev and ra[r] < s_next:
            s_next = ra[r]
        if rb[r] > s_prev and rb[r] < s_next:
            s_next = rb[r]
        if rc[r] > s_prev and rc[r] < s_next:
            s_next = rc[r]
    return s_next


@wp.func
def prism_edges(d: Any, a0: Any, da: Any, b0: Any, db: Any, c0: Any, dc: Any, vi: wp.vec3i, tol: Any):
    """The three edge quadratics of a moving triangle at a ray (eye-relative vertices at the span's
    start a0, b0, c0 and their changes da, db, dc): coefficients, roots in (0, 1) and degeneracy."""
    ca = edge_coeffs(d, a0, da, b0, db, vi[0], vi[1])
    cb = edge_coeffs(d, b0, db, c0, dc, vi[1], vi[2])
    cc = edge_coeffs(d, c0, dc, a0, da, vi[2], vi[0])
    dga = edge_degenerate(ca, d, a0, da, b0, db, tol)
    dgb = edge_degenerate(cb, d, b0, db, c0, dc, tol)
    dgc = edge_degenerate(cc, d, c0, dc, a0, da, tol)
    return ca, cb, cc, quad_roots(ca), quad_roots(cb), quad_roots(cc), dga, dgb, dgc


#: vec3 rows of an entry's edge table (per edge: P, Q, R; then the edges' K and S; see edge_row)
EDGE_TABLE_WIDTH = wp.constant(11)


@wp.func
def edge_row(a0: wp.vec3, da: wp.vec3, b0: wp.vec3, db: wp.vec3, ia: int, ib: int):
    """(P, Q, R, K, S) of the edge from a(s) = a0 + s da to b(s) (eye-relative): edge_vectors, so
    that for any ray d from the eye edge_coeffs = (d·P, d·Q, d·R), and edge_degenerate's scales:
    its bound is d·d × K, its scale |d| × S."""
    p, q, r = edge_vectors(a0, da, b0, db, ia, ib)
    f0 = b0 - a0
    df = db - da
    k = 2.0 * (wp.dot(a0, a0) + wp.dot(da, da)) * 2.0 * (wp.dot(f0, f0) + wp.dot(df, df))
    s = (wp.length(a0) + wp.length(da)) * (wp.length(f0) + wp.length(df))
    return p, q, r, k, s


@wp.kernel(enable_backward=False)
def edge_table(positions: wp.array2d(dtype=wp.vec3), tri_vertices: wp.array(dtype=wp.vec3i),
               entry_tri: wp.array(dtype=int), entry_k0: wp.array(dtype=int), entry_k1: wp.array(dtype=int),
               # output
               table: wp.array2d(dtype=wp.vec3)):
    """table[e] (EDGE_TABLE_WIDTH vec3) for moving entry e: its three edges' edge_row, the
    vertices eye-relative for a pinhole camera (the eye at the camera-space origin). What every
    pixel ray's prism_edges would compute from the vertices, computed once an entry."""
    e = wp.tid()
    k0 = entry_k0[e]
    k1 = entry_k1[e]
    if k0 == k1:
        return
    vi = tri_vertices[entry_tri[e]]
    a0 = positions[k0, vi[0]]
    b0 = positions[k0, vi[1]]
    c0 = positions[k0, vi[2]]
    da = positions[k1, vi[0]] - a0
    db = positions[k1, vi[1]] - b0
    dc = positions[k1, vi[2]] - c0
    pa, qa, ra, ka, sa = edge_row(a0, da, b0, db, vi[0], vi[1])
    pb, qb, rb, kb, sb = edge_row(b0, db, c0, dc, vi[1], vi[2])
    pc, qc, rc, kc, sc = edge_row(c0, dc, a0, da, vi[2], vi[0])
    table[e, 0] = pa
    table[e, 1] = qa
    table[e, 2] = ra
    table[e, 3] = pb
    table[e, 4] = qb
    table[e, 5] = rb
    table[e, 6] = pc
    table[e, 7] = qc
    table[e, 8] = rc
    table[e, 9] = wp.vec3(ka, kb, kc)
    table[e, 10] = wp.vec3(sa, sb, sc)


@wp.func
def table_edge(table: wp.array2d(dtype=wp.vec3), e: int, j: int, d: wp.vec3, tol: float):
    """(coefficients, degenerate) of edge j of entry e at ray d from its table row: equal to
    edge_coeffs and edge_degenerate's."""
    coef = wp.vec3(wp.dot(d, table[e, 3 * j]), wp.dot(d, table[e, 3 * j + 1]), wp.dot(d, table[e, 3 * j + 2]))
    big = wp.max(wp.max(wp.abs(coef[0]), wp.abs(coef[1])), wp.abs(coef[2]))
    degenerate = int(0)
    if big * big <= tol * tol * (wp.dot(d, d) * table[e, 9][j]):
        if big <= tol * wp.length(d) * table[e, 10][j]:
            degenerate = 1
    return coef, degenerate


@wp.func
def prism_edges_table(table: wp.array2d(dtype=wp.vec3), e: int, d: wp.vec3, tol: float):
    """prism_edges of moving entry e at ray d from the eye, from its edge_table row: three dot
    products an edge instead of four cross products."""
    ca, dga = table_edge(table, e, 0, d, tol)
    cb, dgb = table_edge(table, e, 1, d, tol)
    cc, dgc = table_edge(table, e, 2, d, tol)
    return ca, cb, cc, quad_roots(ca), quad_roots(cb), quad_roots(cc), dga, dgb, dgc


@wp.func
def entry_edges(view: View, geo: Geometry, e: int, d: wp.vec3, a0: wp.vec3, da: wp.vec3, b0: wp.vec3, db: wp.vec3,
                c0: wp.vec3, dc: wp.vec3, vi: wp.vec3i):
    """prism_edges of moving entry e at ray d (its eye-relative vertices a0.. and changes da..):
    from the entry's edge table when the frame has one and the rays leave from the eye."""
    if view.ortho == 0 and geo.entry_edges.shape[1] == EDGE_TABLE_WIDTH:
        return prism_edges_table(geo.entry_edges, e, d, DEGENERATE_TOL_F32)
    return prism_edges(d, a0, da, b0, db, c0, dc, vi, DEGENERATE_TOL_F32)


@wp.func
def piece_covered(ca: Any, cb: Any, cc: Any, dga: int, dgb: int, dgc: int, a0: Any, da: Any, b0: Any,
                  db: Any, c0: Any, dc: Any, vi: wp.vec3i, sm: Any, conservative: int) -> int:
    """1 when the piece whose midpoint is sm is covered (all three edge functions share a sign
    there). conservative = 1 lets a degenerate edge pass either way (for bounds; the exact
    per-sample test then decides)."""
    pa = a0 + sm * da
    pb = b0 + sm * db
    pc = c0 + sm * dc
    e1 = edge_sides(ca, dga, sm, pa, pb, vi[0], vi[1])
    e2 = edge_sides(cb, dgb, sm, pb, pc, vi[1], vi[2])
    e3 = edge_sides(cc, dgc, sm, pc, pa, vi[2], vi[0])
    one = type(sm)(1.0)
    zero = type(sm)(0.0)
    if conservative != 0:
        if dga != 0:
            e1 = wp.vector(one, one)
        if dgb != 0:
            e2 = wp.vector(one, one)
        if dgc != 0:
            e3 = wp.vector(one, one)
    if (e1[0] * e2[0] * e3[0] > zero) or (e1[1] * e2[1] * e3[1] > zero):
        return 1
    return 0


@wp.kernel(enable_backward=False)
def coverage_times(p0: wp.array2d(dtype=Any), p1: wp.array2d(dtype=Any), origin: wp.array(dtype=Any),
                   direction: wp.array(dtype=Any), vi: wp.array(dtype=wp.vec3i), tol: Any,
                   # outputs
                   covered: wp.array(dtype=Any), pieces: wp.array(dtype=int)):
    """Case i: triangle p0[i] (3 camera-space vertices at the span's start) moving linearly to p1[i],
    ray origin[i] + t direction[i]: the covered share of the span and the number of covered pieces,
    by the renderer's own coverage functions, in the precision of the arrays."""
    i = wp.tid()
    o = origin[i]
    d = direction[i]
    a0 = p0[i, 0] - o
    b0 = p0[i, 1] - o
    c0 = p0[i, 2] - o
    da = p1[i, 0] - p0[i, 0]
    db = p1[i, 1] - p0[i, 1]
    dc = p1[i, 2] - p0[i, 2]
    ca, cb, cc, ra, rb, rc, dga, dgb, dgc = prism_edges(d, a0, da, b0, db, c0, dc, vi[i], tol)
    total = tol * type(tol)(0.0)
    n = int(0)
    s_prev = tol * type(tol)(0.0)
    for _step in range(MAX_SPAN_PIECES):
        if s_prev < type(tol)(1.0):
            s_next = next_breakpoint(ra, rb, rc, s_prev)
            sm = type(tol)(0.5) * (s_prev + s_next)
            if piece_covered(ca, cb, cc, dga, dgb, dgc, a0, da, b0, db, c0, dc, vi[i], sm, 0) != 0:
                total = total + (s_next - s_prev)
                n = n + 1
            s_prev = s_next
    covered[i] = total
    pieces[i] = n

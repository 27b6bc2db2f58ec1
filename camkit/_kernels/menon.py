"""Menon demosaicing as one streaming pass (kernels for :func:`camkit.sensor.demosaic`).

D. Menon, S. Andriani and G. Calvagno, "Demosaicing with directional filtering and a
posteriori decision", IEEE Trans. Image Processing 16(1), 2007: directional green estimates
(G_H, G_V), a decision by the chrominance gradients summed over a 5x5 window, red and blue
from colour differences along the chosen direction, and the paper's refinement step.

Layout. The stages run row by row, one after another with a fixed lag, on ring buffers of
``RING`` rows per plane (the planes of a 12 MP image never exist in full: they stayed in
memory at ~48 MB each and were written and read back once per stage, which with the page
faults of their first touch made the old multi-pass version several times slower). Within a ring row
the columns are stored deinterleaved, even columns then odd ones, so that every stage's
loop over one kind of site (red/blue or green) runs over contiguous memory and vectorises.
The image is cut into horizontal strips run in parallel
each strip starts its pipeline 10
rows early, enough for every stage's reach, so strips agree with a single pass exactly.

Stage order within one step t (row in brackets), each reading only rows its predecessors
have finished and that later stages have not yet overwritten:
  S0 (t+10) copy the mosaic row, deinterleaved
  S1 (t+8) G_H, G_V
  S2 (t+6) chrominance
  gradients D_H, D_V
  S3 (t+4) decision, G
  S4 (t+3) R, B at green sites
  S5, S6 (t+2)
  R at blue / B at red sites, refined G at red/blue sites
  S7 (t+1) R, B at green sites
  again from the refined G
  S8, S9 (t) refined R at blue / B at red sites, output row.

Borders mirror without repeating the edge pixel (d c b | a b c d), which keeps the Bayer
phase, as the other demosaicing kernels do. Arithmetic is in the planes' dtype (float32 for
integer and float32 mosaics, float64 for float64 ones) except the decision's window sums,
which are float64 so that equal sums tie exactly."""

from __future__ import annotations

import numpy as np
from numba import njit, prange

from camkit._kernels.demosaic import m, put

RING = 16
MASK = RING - 1


@njit(cache=True, nogil=True, error_model="numpy")
def ms(i, n):  # pragma: no cover - numba
    """Mirror index (reflect-101) for any offset (``m`` reflects once, enough for offsets up
    to n - 1); 0 when n == 1."""
    if n == 1:
        return 0
    while i < 0 or i >= n:
        i = m(i, n)
    return i


@njit(cache=True, nogil=True, error_model="numpy")
def pos(x, E):  # pragma: no cover - numba
    """Index of column x in a deinterleaved row whose even half has E entries."""
    return (x >> 1) + (x & 1) * E


@njit(cache=True, nogil=True, error_model="numpy")
def _layout(code, y, W):  # pragma: no cover - numba
    """Row y's sites: (cpar, cb, gb, nC, nG, colour): the column parity of its red or blue
    sites, where their half and the green half start, how many of each, and their colour
    (0 red, 2 blue)."""
    E = (W + 1) // 2
    p = y & 1
    if code[2 * p] != 1:  # colour sites on even columns
        return 0, 0, E, E, W - E, code[2 * p]
    return 1, E, 0, W - E, E, code[2 * p + 1]


@njit(cache=True, nogil=True, error_model="numpy")
def _s0(cfa, y, c, W):  # pragma: no cover - numba
    """S0: mosaic row y into the ring, deinterleaved."""
    row = cfa[y]
    o = c[y & MASK]
    E = (W + 1) // 2
    odd = o[E:]
    for j in range(W // 2):
        o[j] = row[2 * j]
        odd[j] = row[2 * j + 1]
    if W & 1:
        o[E - 1] = row[W - 1]


@njit(cache=True, nogil=True, error_model="numpy")
def _s1(code, H, W, y, c, gh, gv, half, quarter):  # pragma: no cover - numba
    """S1: directional green estimates G_H, G_V (the raw value at green sites)."""
    E = (W + 1) // 2
    c0 = c[y & MASK]
    cm1 = c[ms(y - 1, H) & MASK]
    cp1 = c[ms(y + 1, H) & MASK]
    cm2 = c[ms(y - 2, H) & MASK]
    cp2 = c[ms(y + 2, H) & MASK]
    o_h = gh[y & MASK]
    o_v = gv[y & MASK]
    cpar, cb, gb, nC, nG, _ = _layout(code, y, W)
    a = c0[gb:]
    oh = o_h[gb:]
    ov = o_v[gb:]
    for j in range(nG):
        oh[j] = a[j]
        ov[j] = a[j]
    a = c0[cb:]
    u1 = cm1[cb:]
    d1 = cp1[cb:]
    u2 = cm2[cb:]
    d2 = cp2[cb:]
    ov = o_v[cb:]
    for j in range(nC):
        ov[j] = half * (u1[j] + d1[j]) + half * a[j] - quarter * (u2[j] + d2[j])
    j1 = min(nC - 1, nG - cpar)
    if j1 > 1:
        G = c0[gb + cpar:]  # x -+ 1 of colour site j = i + 1: green half i + cpar, i + 1 + cpar
        C = c0[cb:]
        O = o_h[cb + 1:]
        for i in range(j1 - 1):
            O[i] = half * (G[i] + G[i + 1]) + half * C[i + 1] - quarter * (C[i] + C[i + 2])
    for j in range(nC):
        if 1 <= j < j1:
            continue
        x = 2 * j + cpar
        o_h[cb + j] = (half * (c0[pos(ms(x - 1, W), E)] + c0[pos(ms(x + 1, W), E)]) + half * c0[cb + j]
                       - quarter * (c0[pos(ms(x - 2, W), E)] + c0[pos(ms(x + 2, W), E)]))


@njit(cache=True, nogil=True, error_model="numpy")
def _s2(code, H, W, y, c, gh, gv, dh, dv):  # pragma: no cover - numba
    """S2: chrominance gradients |C(x) - C(x + 2)| along the row and down the column, with
    C = colour - G at red/blue sites; 0 at green sites (two along is green too)."""
    E = (W + 1) // 2
    y2 = ms(y + 2, H)
    c0 = c[y & MASK]
    c2 = c[y2 & MASK]
    h0 = gh[y & MASK]
    v0 = gv[y & MASK]
    v2 = gv[y2 & MASK]
    o_h = dh[y & MASK]
    o_v = dv[y & MASK]
    cpar, cb, gb, nC, nG, _ = _layout(code, y, W)
    oh = o_h[gb:]
    ov = o_v[gb:]
    for j in range(nG):
        oh[j] = 0.0
        ov[j] = 0.0
    C = c0[cb:]
    Hh = h0[cb:]
    V = v0[cb:]
    C2 = c2[cb:]
    V2 = v2[cb:]
    oh = o_h[cb:]
    ov = o_v[cb:]
    for j in range(nC):
        ov[j] = abs((C[j] - V[j]) - (C2[j] - V2[j]))
    for j in range(nC - 1):
        oh[j] = abs((C[j] - Hh[j]) - (C[j + 1] - Hh[j + 1]))
    if nC >= 1:
        j = nC - 1
        x2 = pos(ms(2 * j + cpar + 2, W), E)
        o_h[cb + j] = abs((c0[cb + j] - h0[cb + j]) - (c0[x2] - h0[x2]))


@njit(cache=True, nogil=True, error_model="numpy")
def _win(d, H, W, y, x, ty):  # pragma: no cover - numba
    """The paper's 5x5 classifier window on the ring (zeros outside the image): weight 3 at
    offsets (0, 0), (0, -2); 1 at (2, 0), (2, -2), (1, -1), (-1, -1), (-2, 0), (-2, -2), read
    as (dy, dx) for the horizontal classifier (ty = 1), transposed for the vertical one."""
    E = (W + 1) // 2
    s = 0.0
    for oy, ox, w in ((0, 0, 3.0), (0, -2, 3.0), (2, 0, 1.0), (2, -2, 1.0), (1, -1, 1.0),
                      (-1, -1, 1.0), (-2, 0, 1.0), (-2, -2, 1.0)):
        yy = y + (oy if ty else ox)
        xx = x + (ox if ty else oy)
        if 0 <= yy < H and 0 <= xx < W:
            s += w * d[yy & MASK, pos(xx, E)]
    return s


@njit(cache=True, nogil=True, error_model="numpy")
def _decide_px(H, W, y, x, gh, gv, dh, dv, g, hz):  # pragma: no cover - numba
    """S3 at one border pixel (bounds-checked windows)."""
    E = (W + 1) // 2
    k = pos(x, E)
    sh = _win(dh, H, W, y, x, 1)
    sv = _win(dv, H, W, y, x, 0)
    hv = gh[y & MASK, k]
    vw = gv[y & MASK, k]
    hz[y & MASK, k] = np.uint8(sv >= sh)
    if abs(sv - sh) <= 1e-6 * (sv + sh):
        g[y & MASK, k] = 0.5 * (hv + vw)
    else:
        g[y & MASK, k] = hv if sv >= sh else vw


@njit(cache=True, nogil=True, error_model="numpy")
def _s3(H, W, y, gh, gv, dh, dv, g, hz, half):  # pragma: no cover - numba
    """S3: keep the direction whose chrominance varies less, G = G_H where sum(D_V) >= sum(D_H)
    else G_V, their mean on a tie (equal within 1e-6 relative; the paper is silent on ties)."""
    E = (W + 1) // 2
    h0 = gh[y & MASK]
    v0 = gv[y & MASK]
    go = g[y & MASK]
    ho = hz[y & MASK]
    if 2 <= y < H - 2 and W > 4:
        a = dh[(y - 2) & MASK]
        b = dh[(y - 1) & MASK]
        c = dh[y & MASK]
        d = dh[(y + 1) & MASK]
        e = dh[(y + 2) & MASK]
        va = dv[(y - 2) & MASK]
        vb = dv[(y - 1) & MASK]
        vc = dv[y & MASK]
        for q in range(2):
            hb = q * E
            ob = (1 - q) * E + q  # other half, shifted so that x - 1 is index i
            n = (W - 3 - q) // 2  # j = 1 .. n, i = j - 1
            aH = a[hb:]
            cH = c[hb:]
            eH = e[hb:]
            vaH = va[hb:]
            vcH = vc[hb:]
            bO = b[ob:]
            dO = d[ob:]
            vbO = vb[ob:]
            hh = h0[hb + 1:]
            vv = v0[hb + 1:]
            gg = go[hb + 1:]
            oo = ho[hb + 1:]
            for i in range(n):
                # float64 sums (the 3.0 promotes), as the tie test below needs them exact
                sh = (3.0 * (cH[i + 1] + cH[i]) + eH[i + 1] + eH[i] + dO[i] + bO[i] + aH[i + 1] + aH[i])
                sv = (3.0 * (vcH[i + 1] + vaH[i + 1]) + vcH[i + 2] + vaH[i + 2] + vbO[i + 1] + vbO[i]
                      + vcH[i] + vaH[i])
                hv = hh[i]
                vw = vv[i]
                hor = sv >= sh
                oo[i] = np.uint8(hor)
                avg = half * (hv + vw)
                pick = hv if hor else vw
                gg[i] = avg if abs(sv - sh) <= 1e-6 * (sv + sh) else pick
        for x in (0, 1, W - 2, W - 1):
            _decide_px(H, W, y, x, gh, gv, dh, dv, g, hz)
    else:
        for x in range(W):
            _decide_px(H, W, y, x, gh, gv, dh, dv, g, hz)


@njit(cache=True, nogil=True, error_model="numpy")
def _colour_green(code, H, W, y, c, g, r, b, half):  # pragma: no cover - numba
    """R and B at the green sites of row y: G plus the mean colour-minus-G of the two
    neighbours that carry the colour (left/right for the row's colour, up/down for the other)."""
    E = (W + 1) // 2
    yu = ms(y - 1, H)
    yd = ms(y + 1, H)
    c0 = c[y & MASK]
    cu = c[yu & MASK]
    cd = c[yd & MASK]
    g0 = g[y & MASK]
    gu = g[yu & MASK]
    gd = g[yd & MASK]
    cpar, cb, gb, nC, nG, colour = _layout(code, y, W)
    gp = 1 - cpar
    if colour == 0:
        along = r[y & MASK]
        across = b[y & MASK]
    else:
        along = b[y & MASK]
        across = r[y & MASK]
    G = g0[gb:]
    CU = cu[gb:]
    GU = gu[gb:]
    CD = cd[gb:]
    GD = gd[gb:]
    A = across[gb:]
    for j in range(nG):
        A[j] = G[j] + half * ((CU[j] - GU[j]) + (CD[j] - GD[j]))
    j1 = min(nG, nC - gp)  # green site j: x -+ 1 -> colour half j - 1 + gp, j + gp
    if j1 > 1:
        C = c0[cb + gp:]
        Gc = g0[cb + gp:]
        Gg = g0[gb + 1:]
        L = along[gb + 1:]
        for i in range(j1 - 1):
            L[i] = Gg[i] + half * ((C[i] - Gc[i]) + (C[i + 1] - Gc[i + 1]))
    for j in range(nG):
        if 1 <= j < j1:
            continue
        x = 2 * j + gp
        xl = pos(ms(x - 1, W), E)
        xr = pos(ms(x + 1, W), E)
        along[gb + j] = g0[gb + j] + half * ((c0[xl] - g0[xl]) + (c0[xr] - g0[xr]))


@njit(cache=True, nogil=True, error_model="numpy")
def _s4(code, H, W, y, c, g, r, b, half):  # pragma: no cover - numba
    """S4: the raw colour at red/blue sites, then R and B at green sites."""
    c0 = c[y & MASK]
    _, cb, _, nC, _, colour = _layout(code, y, W)
    if colour == 0:
        own = r[y & MASK, cb:]
        other = b[y & MASK, cb:]
    else:
        own = b[y & MASK, cb:]
        other = r[y & MASK, cb:]
    a = c0[cb:]
    for j in range(nC):
        own[j] = a[j]
        other[j] = 0.0
    _colour_green(code, H, W, y, c, g, r, b, half)


@njit(cache=True, nogil=True, error_model="numpy")
def _cross(code, H, W, y, hz, r, b, with_centre, half, three):  # pragma: no cover - numba
    """S5 / S8: R at blue and B at red sites from R - B along the chosen direction: the two
    neighbours' mean, or (refinement) with the centre's current difference as a third tap."""
    E = (W + 1) // 2
    yu = ms(y - 1, H)
    yd = ms(y + 1, H)
    r0 = r[y & MASK]
    b0 = b[y & MASK]
    ru = r[yu & MASK]
    bu = b[yu & MASK]
    rd = r[yd & MASK]
    bd = b[yd & MASK]
    h = hz[y & MASK]
    cpar, cb, gb, nC, nG, colour = _layout(code, y, W)
    blue = colour == 2
    j1 = min(nC, nG - cpar)  # colour site j: x -+ 1 -> green half j - 1 + cpar, j + cpar
    if j1 > 1:
        RG = r0[gb + cpar:]
        BG = b0[gb + cpar:]
        R0 = r0[cb + 1:]
        B0 = b0[cb + 1:]
        RU = ru[cb + 1:]
        BU = bu[cb + 1:]
        RD = rd[cb + 1:]
        BD = bd[cb + 1:]
        Hh = h[cb + 1:]
        n = j1 - 1
        # Four copies of the loop, so that none tests blue or with_centre per site (one
        # loop with the tests inside, left to the compiler to unswitch, was 10% slower).
        if blue:
            if with_centre:
                for i in range(n):
                    hh = Hh[i]
                    a0 = (RG[i] - BG[i]) if hh else (RU[i] - BU[i])
                    a1 = (RG[i + 1] - BG[i + 1]) if hh else (RD[i] - BD[i])
                    R0[i] = B0[i] + (a0 + a1 + (R0[i] - B0[i])) / three
            else:
                for i in range(n):
                    hh = Hh[i]
                    a0 = (RG[i] - BG[i]) if hh else (RU[i] - BU[i])
                    a1 = (RG[i + 1] - BG[i + 1]) if hh else (RD[i] - BD[i])
                    R0[i] = B0[i] + half * (a0 + a1)
        else:
            if with_centre:
                for i in range(n):
                    hh = Hh[i]
                    a0 = (RG[i] - BG[i]) if hh else (RU[i] - BU[i])
                    a1 = (RG[i + 1] - BG[i + 1]) if hh else (RD[i] - BD[i])
                    B0[i] = R0[i] - (a0 + a1 + (R0[i] - B0[i])) / three
            else:
                for i in range(n):
                    hh = Hh[i]
                    a0 = (RG[i] - BG[i]) if hh else (RU[i] - BU[i])
                    a1 = (RG[i + 1] - BG[i + 1]) if hh else (RD[i] - BD[i])
                    B0[i] = R0[i] - half * (a0 + a1)
    for j in range(nC):
        if 1 <= j < j1:
            continue
        x = 2 * j + cpar
        k = cb + j
        xl = pos(ms(x - 1, W), E)
        xr = pos(ms(x + 1, W), E)
        if h[k]:
            a0 = r0[xl] - b0[xl]
            a1 = r0[xr] - b0[xr]
        else:
            a0 = ru[k] - bu[k]
            a1 = rd[k] - bd[k]
        d = (a0 + a1 + (r0[k] - b0[k])) / three if with_centre else half * (a0 + a1)
        if blue:
            r0[k] = b0[k] + d
        else:
            b0[k] = r0[k] - d


@njit(cache=True, nogil=True, error_model="numpy")
def _s6(code, H, W, y, hz, g, r, b, three):  # pragma: no cover - numba
    """S6 (refinement): G at red/blue sites from the 3-tap mean of colour - G along the
    chosen direction."""
    E = (W + 1) // 2
    yu = ms(y - 1, H)
    yd = ms(y + 1, H)
    g0 = g[y & MASK]
    gu = g[yu & MASK]
    gd = g[yd & MASK]
    h = hz[y & MASK]
    cpar, cb, gb, nC, nG, colour = _layout(code, y, W)
    own = r if colour == 0 else b
    o0 = own[y & MASK]
    ou = own[yu & MASK]
    od = own[yd & MASK]
    j1 = min(nC, nG - cpar)
    if j1 > 1:
        OG = o0[gb + cpar:]
        GG = g0[gb + cpar:]
        O = o0[cb + 1:]
        G = g0[cb + 1:]
        OU = ou[cb + 1:]
        GU = gu[cb + 1:]
        OD = od[cb + 1:]
        GD = gd[cb + 1:]
        Hh = h[cb + 1:]
        for i in range(j1 - 1):
            if Hh[i]:
                d = ((OG[i] - GG[i]) + (O[i] - G[i]) + (OG[i + 1] - GG[i + 1])) / three
            else:
                d = ((OU[i] - GU[i]) + (O[i] - G[i]) + (OD[i] - GD[i])) / three
            G[i] = O[i] - d
    for j in range(nC):
        if 1 <= j < j1:
            continue
        x = 2 * j + cpar
        k = cb + j
        xa = pos(ms(x - 1, W), E)
        xb = pos(ms(x + 1, W), E)
        if h[k]:
            d = ((o0[xa] - g0[xa]) + (o0[k] - g0[k]) + (o0[xb] - g0[xb])) / three
        else:
            d = ((ou[k] - gu[k]) + (o0[k] - g0[k]) + (od[k] - gd[k])) / three
        g0[k] = o0[k] - d


@njit(cache=True, nogil=True, error_model="numpy")
def _s9(W, y, g, r, b, is_int, hi, out):  # pragma: no cover - numba
    """S9: interleave the row into the output, rounding and saturating integer outputs."""
    E = (W + 1) // 2
    r0 = r[y & MASK]
    g0 = g[y & MASK]
    b0 = b[y & MASK]
    ro = r0[E:]
    go = g0[E:]
    bo = b0[E:]
    o = out[y].reshape(-1)
    for j in range(W // 2):
        o[6 * j] = put(r0[j], is_int, hi)
        o[6 * j + 1] = put(g0[j], is_int, hi)
        o[6 * j + 2] = put(b0[j], is_int, hi)
        o[6 * j + 3] = put(ro[j], is_int, hi)
        o[6 * j + 4] = put(go[j], is_int, hi)
        o[6 * j + 5] = put(bo[j], is_int, hi)
    if W & 1:
        o[3 * W - 3] = put(r0[E - 1], is_int, hi)
        o[3 * W - 2] = put(g0[E - 1], is_int, hi)
        o[3 * W - 1] = put(b0[E - 1], is_int, hi)


@njit(cache=True, nogil=True, parallel=True, error_model="numpy")
def menon(cfa: np.ndarray, code: np.ndarray, consts: np.ndarray, is_int: bool, hi: float,
          out: np.ndarray) -> None:  # pragma: no cover - numba
    """Demosaic ``cfa`` (H, W) into ``out`` (H, W, 3), C-contiguous. ``code``: the pattern's
    2x2 colour indices
    ``consts``: [0.5, 0.25, 3.0] in the working dtype (float32 or
    float64), which sets the planes' dtype
    integer outputs are rounded half up and
    saturated to [0, hi]."""
    H, W = cfa.shape
    half = consts[0]
    quarter = consts[1]
    three = consts[2]
    n_strips = max(1, min(H // 64, 8))
    for s in prange(n_strips):
        y0 = (H * s) // n_strips
        y1 = (H * (s + 1)) // n_strips
        lo = max(0, y0 - 10)
        c = np.empty((RING, W), consts.dtype)
        gh = np.empty((RING, W), consts.dtype)
        gv = np.empty((RING, W), consts.dtype)
        dh = np.empty((RING, W), consts.dtype)
        dv = np.empty((RING, W), consts.dtype)
        g = np.empty((RING, W), consts.dtype)
        hz = np.empty((RING, W), np.uint8)
        r = np.empty((RING, W), consts.dtype)
        b = np.empty((RING, W), consts.dtype)
        for t in range(lo - 10, y1):
            y = t + 10
            if lo <= y < H:
                _s0(cfa, y, c, W)
            y = t + 8
            if lo <= y < H:
                _s1(code, H, W, y, c, gh, gv, half, quarter)
            y = t + 6
            if lo <= y < H:
                _s2(code, H, W, y, c, gh, gv, dh, dv)
            y = t + 4
            if lo <= y < H:
                _s3(H, W, y, gh, gv, dh, dv, g, hz, half)
            y = t + 3
            if lo <= y < H:
                _s4(code, H, W, y, c, g, r, b, half)
            y = t + 2
            if lo <= y < H:
                _cross(code, H, W, y, hz, r, b, False, half, three)
                _s6(code, H, W, y, hz, g, r, b, three)
            y = t + 1
            if lo <= y < H:
                _colour_green(code, H, W, y, c, g, r, b, half)
            y = t
            if y0 <= y < H:
                _cross(code, H, W, y, hz, r, b, True, half, three)
                _s9(W, y, g, r, b, is_int, hi, out)

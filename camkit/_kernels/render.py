"""Rendering a planar target: ray-plane intersection and footprint-integrated shading."""

from __future__ import annotations

import math

import numpy as np
from numba import njit, prange


@njit(cache=True, nogil=True, parallel=True, error_model="numpy")
def plane_coords(rays: np.ndarray, R: np.ndarray, t: np.ndarray, out: np.ndarray) -> None:  # pragma: no cover
    """Target-plane coordinates (u, v) where each camera ray meets the plane z_target = 0.

    ``X_cam = R X_target + t``; the plane's normal in the camera frame is R[:, 2] and it
    contains t, so the ray ``s d`` meets it at ``s = (n . t) / (n . d)``; NaN if the ray misses
    (parallel, behind the camera, or NaN)."""
    nx, ny, nz = R[0, 2], R[1, 2], R[2, 2]
    nt = nx * t[0] + ny * t[1] + nz * t[2]
    for y in prange(rays.shape[0]):
        for x in range(rays.shape[1]):
            dx, dy, dz = rays[y, x, 0], rays[y, x, 1], rays[y, x, 2]
            nd = nx * dx + ny * dy + nz * dz
            s = nt / nd
            if not (s > 0.0):
                out[y, x, 0] = np.nan
                out[y, x, 1] = np.nan
                continue
            px = s * dx - t[0]
            py = s * dy - t[1]
            pz = s * dz - t[2]
            out[y, x, 0] = R[0, 0] * px + R[1, 0] * py + R[2, 0] * pz
            out[y, x, 1] = R[0, 1] * px + R[1, 1] * py + R[2, 1] * pz


@njit(cache=True, nogil=True, error_model="numpy")
def footprint(uv: np.ndarray, y: int, x: int):  # pragma: no cover
    """Local affine map from pixel offsets to plane coordinates at (y, x): central differences
    of the neighbours' intersections (one-sided where a neighbour misses the plane).
    Returns (du/dx, dv/dx, du/dy, dv/dy)."""
    H, W = uv.shape[0], uv.shape[1]
    xl = x - 1 if x > 0 and math.isfinite(uv[y, x - 1, 0]) else x
    xr = x + 1 if x < W - 1 and math.isfinite(uv[y, x + 1, 0]) else x
    yu = y - 1 if y > 0 and math.isfinite(uv[y - 1, x, 0]) else y
    yd = y + 1 if y < H - 1 and math.isfinite(uv[y + 1, x, 0]) else y
    sx = 1.0 / max(xr - xl, 1)
    sy = 1.0 / max(yd - yu, 1)
    return ((uv[y, xr, 0] - uv[y, xl, 0]) * sx, (uv[y, xr, 1] - uv[y, xl, 1]) * sx,
            (uv[yd, x, 0] - uv[yu, x, 0]) * sy, (uv[yd, x, 1] - uv[yu, x, 1]) * sy)


@njit(cache=True, nogil=True, error_model="numpy")
def checker(u: float, v: float, square: float, ext: np.ndarray, black: float, white: float,
            background: float) -> float:  # pragma: no cover
    """Reflectance of the board at (u, v): black where floor(u/s) + floor(v/s) is even,
    white otherwise and in the margin, background off the sheet."""
    if not (ext[0] <= u < ext[2] and ext[1] <= v < ext[3]):
        return background
    a = math.floor(u / square)
    b = math.floor(v / square)
    if a < -1 or b < -1 or a >= ext[4] or b >= ext[5]:
        return white  # margin: the squares have indices -1 .. inner_cols - 1 (and rows alike)
    return black if (a + b) % 2 == 0 else white


@njit(cache=True, nogil=True, parallel=True, error_model="numpy")
def shade(uv: np.ndarray, square: float, ext: np.ndarray, black: float, white: float,
          bg: np.ndarray, N: int, g: int, out: np.ndarray) -> None:  # pragma: no cover
    """Each pixel's mean reflectance over its footprint: the target coordinates of the pixel
    square [x-1/2, x+1/2] x [y-1/2, y+1/2] are mapped by the local affine approximation from
    the neighbours' coordinates (central differences), sampled at the N points of a rank-1
    lattice with generator g, ``((k + 1/2) / N, ((k g mod N) + 1/2) / N)`` (I. H. Sloan and
    S. Joe, *Lattice Methods for Multiple Integration*, 1994; g chosen by
    ``camkit.render.target.edge_lattice``). Every sample has its own row and its own column, so
    an edge along a pixel row or column is resolved to 1/N of a pixel (an upright S x S grid
    resolves it to 1/S: corners were off by up to 0.023 px). A footprint
    inside one square (or entirely off the sheet) takes its value without sampling."""
    H, W = uv.shape[0], uv.shape[1]
    offs = np.empty((N, 2))
    for k in range(N):
        offs[k, 0] = (k + 0.5) / N - 0.5
        offs[k, 1] = ((k * g) % N + 0.5) / N - 0.5
    for yy in prange(H):
        y = np.int64(yy)  # the parallel index is unsigned; y - 1 must stay an int
        for x in range(W):
            background = bg[y, x]  # this pixel's background: a constant or a texture
            u0 = uv[y, x, 0]
            v0 = uv[y, x, 1]
            if not (math.isfinite(u0) and math.isfinite(v0)):
                out[y, x] = background
                continue
            jux, jvx, juy, jvy = footprint(uv, y, x)
            # Bounding box of the footprint: is it inside one square?
            hu = 0.5 * (abs(jux) + abs(juy))
            hv = 0.5 * (abs(jvx) + abs(jvy))
            c0 = checker(u0 - hu, v0 - hv, square, ext, black, white, background)
            same = (math.floor((u0 - hu) / square) == math.floor((u0 + hu) / square)
                    and math.floor((v0 - hv) / square) == math.floor((v0 + hv) / square)
                    and c0 == checker(u0 + hu, v0 + hv, square, ext, black, white, background)
                    and c0 == checker(u0 - hu, v0 + hv, square, ext, black, white, background)
                    and c0 == checker(u0 + hu, v0 - hv, square, ext, black, white, background))
            if same:
                out[y, x] = c0
                continue
            # Count samples per region, then weigh once: a footprint that lies in one region
            # after all (it only touched a boundary) gets that region's value exactly.
            n_black = 0
            n_white = 0
            n_back = 0
            for k in range(N):
                ox = offs[k, 0]
                oy = offs[k, 1]
                val = checker(u0 + jux * ox + juy * oy, v0 + jvx * ox + jvy * oy, square, ext,
                              black, white, background)
                if val == black:
                    n_black += 1
                elif val == white:
                    n_white += 1
                else:
                    n_back += 1
            n = N
            if n_black == n:
                out[y, x] = black
            elif n_white == n:
                out[y, x] = white
            elif n_back == n:
                out[y, x] = background
            else:
                out[y, x] = (n_black * black + n_white * white + n_back * background) / n


@njit(cache=True, nogil=True, parallel=True, error_model="numpy")
def plane_depth(rays: np.ndarray, R: np.ndarray, t: np.ndarray, out: np.ndarray) -> None:  # pragma: no cover
    """Depth (camera z) of the board point each ray meets; NaN where it misses."""
    nx, ny, nz = R[0, 2], R[1, 2], R[2, 2]
    nt = nx * t[0] + ny * t[1] + nz * t[2]
    for y in prange(rays.shape[0]):
        for x in range(rays.shape[1]):
            nd = nx * rays[y, x, 0] + ny * rays[y, x, 1] + nz * rays[y, x, 2]
            s = nt / nd
            out[y, x] = s * rays[y, x, 2] if s > 0.0 else np.nan


@njit(cache=True, nogil=True, parallel=True, error_model="numpy")
def disc_blur(img: np.ndarray, radius: np.ndarray, out: np.ndarray) -> None:  # pragma: no cover
    """Spatially varying defocus: each output pixel is the mean of the input over a disc of
    its own radius (pixels), pixels weighted by their area inside the disc (estimated on a
    4x4 sub-grid); radius < 0.5 leaves the pixel as it is. Edges replicate."""
    H, W = img.shape[0], img.shape[1]
    C = img.shape[2]
    for y in prange(H):
        for x in range(W):
            r = radius[y, x]
            if not (r >= 0.5):
                for c in range(C):
                    out[y, x, c] = img[y, x, c]
                continue
            R = int(r + 1.0)
            acc = np.zeros(C)
            wsum = 0.0
            for dy in range(-R, R + 1):
                yy = min(max(y + dy, 0), H - 1)
                for dx in range(-R, R + 1):
                    w = 0.0
                    for sy in range(4):
                        for sx in range(4):
                            ox = dx + (sx + 0.5) / 4.0 - 0.5
                            oy = dy + (sy + 0.5) / 4.0 - 0.5
                            if ox * ox + oy * oy <= r * r:
                                w += 1.0 / 16.0
                    if w > 0.0:
                        xx = min(max(x + dx, 0), W - 1)
                        for c in range(C):
                            acc[c] += w * img[yy, xx, c]
                        wsum += w
            for c in range(C):
                out[y, x, c] = acc[c] / wsum


@njit(cache=True, nogil=True, error_model="numpy")
def texel(tex: np.ndarray, u: float, v: float, size_u: float, size_v: float, c: int) -> float:  # pragma: no cover
    """Bilinear texture value at plane coordinates (u, v) in [0, size_u) x [0, size_v); texel
    centres at ((i + 0.5) size_u / w, ...), edges replicated."""
    h, w = tex.shape[0], tex.shape[1]
    x = u / size_u * w - 0.5
    y = v / size_v * h - 0.5
    x0 = math.floor(x)
    y0 = math.floor(y)
    fx = x - x0
    fy = y - y0
    xa = min(max(x0, 0), w - 1)
    xb = min(max(x0 + 1, 0), w - 1)
    ya = min(max(y0, 0), h - 1)
    yb = min(max(y0 + 1, 0), h - 1)
    return ((1 - fy) * ((1 - fx) * tex[ya, xa, c] + fx * tex[ya, xb, c])
            + fy * ((1 - fx) * tex[yb, xa, c] + fx * tex[yb, xb, c]))


@njit(cache=True, nogil=True, parallel=True, error_model="numpy")
def shade_texture(uv: np.ndarray, tex: np.ndarray, size_u: float, size_v: float, bg: np.ndarray, S: int,
                  out: np.ndarray) -> None:  # pragma: no cover
    """Each pixel's mean over its footprint (S x S samples on the local affine map) of a
    texture on the plane rectangle [0, size_u) x [0, size_v), or the background off it."""
    H, W = uv.shape[0], uv.shape[1]
    C = out.shape[2]
    for yy in prange(H):
        y = np.int64(yy)
        for x in range(W):
            u0 = uv[y, x, 0]
            v0 = uv[y, x, 1]
            if not (math.isfinite(u0) and math.isfinite(v0)):
                for c in range(C):
                    out[y, x, c] = bg[y, x, c]
                continue
            jux, jvx, juy, jvy = footprint(uv, y, x)
            for c in range(C):
                acc = 0.0
                for i in range(S):
                    oy = (i + 0.5) / S - 0.5
                    for j in range(S):
                        ox = (j + 0.5) / S - 0.5
                        u = u0 + jux * ox + juy * oy
                        v = v0 + jvx * ox + jvy * oy
                        if 0.0 <= u < size_u and 0.0 <= v < size_v:
                            acc += texel(tex, u, v, size_u, size_v, c)
                        else:
                            acc += bg[y, x, c]
                out[y, x, c] = acc / (S * S)

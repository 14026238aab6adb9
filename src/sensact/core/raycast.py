"""Fast ray casting against a town of vertical prisms and a ground plane, for the simulated lidar.

Every obstacle is a vertical prism standing on the ground: an axis-aligned box (a building, a parked
car) or a cylinder (a pole, a tree trunk). Their footprints are binned into a uniform 2-D grid, and each
ray walks the grid cells it crosses (Amanatides-Woo) and tests only the prisms listed there, stopping as
soon as the nearest hit lies inside the cells already walked. The rays of one firing are cast in
parallel.
"""

from __future__ import annotations

import numpy as np
from numba import njit, prange

BOX = 0
CYLINDER = 1


def build_grid(kind: np.ndarray, params: np.ndarray, cell_m: float):
    """Bin prism footprints into cells. ``params`` rows: box (x0, y0, x1, y1, h), cylinder (cx, cy, r, h, 0).

    Returns ``(origin_xy, cell_m, shape, cell_start, cell_items)`` in CSR form.
    """
    lo = np.where(kind[:, None] == BOX, params[:, :2], params[:, :2] - params[:, 2:3])
    hi = np.where(kind[:, None] == BOX, params[:, 2:4], params[:, :2] + params[:, 2:3])
    origin = lo.min(axis=0) - cell_m
    shape = np.ceil((hi.max(axis=0) + cell_m - origin) / cell_m).astype(np.int64)
    i0 = np.floor((lo - origin) / cell_m).astype(np.int64)
    i1 = np.floor((hi - origin) / cell_m).astype(np.int64)
    cells, items = [], []
    for k in range(len(kind)):
        xs, ys = np.meshgrid(np.arange(i0[k, 0], i1[k, 0] + 1), np.arange(i0[k, 1], i1[k, 1] + 1), indexing="ij")
        c = (xs * shape[1] + ys).ravel()
        cells.append(c)
        items.append(np.full(c.size, k))
    cells = np.concatenate(cells)
    items = np.concatenate(items)
    order = np.argsort(cells, kind="stable")
    start = np.searchsorted(cells[order], np.arange(shape[0] * shape[1] + 1)).astype(np.int64)
    return origin.astype(float), float(cell_m), shape, start, items[order].astype(np.int64)


@njit(cache=True)
def _hit_box(px, py, pz, dx, dy, dz, b):
    tmin = 0.0
    tmax = 1e30
    lo = (b[0], b[1], 0.0)
    hi = (b[2], b[3], b[4])
    o = (px, py, pz)
    d = (dx, dy, dz)
    for a in range(3):
        if abs(d[a]) < 1e-12:
            if o[a] < lo[a] or o[a] > hi[a]:
                return 1e30
        else:
            t1 = (lo[a] - o[a]) / d[a]
            t2 = (hi[a] - o[a]) / d[a]
            if t1 > t2:
                t1, t2 = t2, t1
            if t1 > tmin:
                tmin = t1
            if t2 < tmax:
                tmax = t2
            if tmin > tmax:
                return 1e30
    return tmin if tmin > 1e-6 else 1e30


@njit(cache=True)
def _hit_cylinder(px, py, pz, dx, dy, dz, c):
    ox = px - c[0]
    oy = py - c[1]
    a = dx * dx + dy * dy
    best = 1e30
    if a > 1e-12:
        b = ox * dx + oy * dy
        cc = ox * ox + oy * oy - c[2] * c[2]
        disc = b * b - a * cc
        if disc >= 0.0:
            t = (-b - disc**0.5) / a
            if t > 1e-6:
                z = pz + t * dz
                if 0.0 <= z <= c[3]:
                    best = t
    if dz < -1e-12 and pz > c[3]:  # the top disc, seen from above
        t = (c[3] - pz) / dz
        x = ox + t * dx
        y = oy + t * dy
        if x * x + y * y <= c[2] * c[2] and t < best:
            best = t
    return best


@njit(cache=True)
def cast_ray(px, py, pz, dx, dy, dz, max_range, kind, params, origin, cell, nx, ny, start, items):
    """Distance along the unit direction ``d`` to the first surface, or 0 if nothing within ``max_range``."""
    best = max_range
    if dz < -1e-12:
        tg = -pz / dz  # the ground plane z = 0
        if tg < best:
            best = tg
    h = (dx * dx + dy * dy) ** 0.5
    if h < 1e-12:
        return best if best < max_range else 0.0
    # Amanatides-Woo walk over the 2-D grid, along the ray's horizontal projection
    gx = (px - origin[0]) / cell
    gy = (py - origin[1]) / cell
    ix = int(np.floor(gx))
    iy = int(np.floor(gy))
    sx = 1 if dx > 0 else -1
    sy = 1 if dy > 0 else -1
    tdx = cell / abs(dx) if abs(dx) > 1e-12 else 1e30
    tdy = cell / abs(dy) if abs(dy) > 1e-12 else 1e30
    if abs(dx) > 1e-12:
        tx = ((ix + (1 if dx > 0 else 0)) - gx) * cell / dx
    else:
        tx = 1e30
    if abs(dy) > 1e-12:
        ty = ((iy + (1 if dy > 0 else 0)) - gy) * cell / dy
    else:
        ty = 1e30
    t_cell_exit = 0.0
    while t_cell_exit < best:
        t_cell_exit = tx if tx < ty else ty
        if 0 <= ix < nx and 0 <= iy < ny:
            c = ix * ny + iy
            for k in range(start[c], start[c + 1]):
                j = items[k]
                if kind[j] == 0:
                    t = _hit_box(px, py, pz, dx, dy, dz, params[j])
                else:
                    t = _hit_cylinder(px, py, pz, dx, dy, dz, params[j])
                if t < best:
                    best = t
        elif (ix < 0 and sx < 0) or (ix >= nx and sx > 0) or (iy < 0 and sy < 0) or (iy >= ny and sy > 0):
            break
        if tx < ty:
            ix += sx
            tx += tdx
        else:
            iy += sy
            ty += tdy
    return best if best < max_range else 0.0


@njit(cache=True, parallel=True)
def cast_firings(
    poses, sensor_height, rot, vert, horiz, mount, max_range, kind, params, origin, cell, nx, ny, start, items, out
):
    """Distances for ``F`` firings of ``n`` lasers into ``out`` (F, n).

    Firing ``f`` is taken at the car pose ``poses[f] = (x, y, theta)`` (theta = 0 faces world +y, as in
    eq. 2.32) with the unit at rotation ``rot[f]``; laser ``l`` points at ``horiz[l] + rot[f] + mount``
    from the car's x axis and ``vert[l]`` above horizontal (eq. 2.35).
    """
    F = poses.shape[0]
    n = vert.shape[0]
    for f in prange(F):
        c = np.cos(poses[f, 2])
        s = np.sin(poses[f, 2])
        for l in range(n):
            a = horiz[l] + rot[f] + mount
            cv = np.cos(vert[l])
            ex = cv * np.cos(a)
            ey = cv * np.sin(a)
            ez = np.sin(vert[l])
            wx = c * ex - s * ey
            wy = s * ex + c * ey
            out[f, l] = cast_ray(
                poses[f, 0],
                poses[f, 1],
                sensor_height,
                wx,
                wy,
                ez,
                max_range,
                kind,
                params,
                origin,
                cell,
                nx,
                ny,
                start,
                items,
            )

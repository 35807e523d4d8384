"""Camera-ray generation as compiled kernels (engine/jit.py): a chunk's samples to pixels
and jittered positions (chunk_samples), and one pass from pixel positions to ray origins,
unit directions and clip distances, for integrator.camera_rays.

The position inside the pixel comes from the pixel filter's inverse CDF
(engine/pixelfilter.py: each ray drawn from the filter's distribution, weight 1, as
Cycles' camera_sample does). With the box filter (empty table) the arithmetic is, operation
by operation, the numpy stage it replaced, so the rays are bitwise identical
(tests/test_camera_rays.py keeps that stage as the oracle).
"""
from __future__ import annotations

import math

import numpy as np

from .jit import kernel, register_warm_up
from .panorama import P_FRAME, Panorama, panorama_direction
from .sampling import pow2_shift


@kernel
def _filter_position(table, u):
    """Position inside the pixel for the uniform number u: the filter table read with
    linear interpolation (pixelfilter.lookup_filter); u itself for an empty table."""
    n = table.shape[0]
    if n == 0:
        return u
    x = min(max(u, 0.0), 1.0) * (n - 1)
    i = min(int(x), n - 1)
    j = min(i + 1, n - 1)
    t = x - i
    return (1.0 - t) * table[i] + t * table[j]


@kernel
def aperture_point(u1, u2, blades, rotation, inv_ratio):
    """A point on the unit aperture for uniform numbers u1, u2 in [0, 1), as Cycles'
    camera_sample_aperture: blades < 3 the unit disk (concentric map, Shirley and Chiu
    1997: sample_uniform_disk), else the regular polygon of `blades` corners on the unit
    circle, turned so that an edge's middle lies at angle `rotation` (rad) from camera x
    (regular_polygon_sample: the triangle of one edge and the centre picked by u1, a
    uniform point in it); x then scaled by inv_ratio (Blender's
    aperture ratio: anamorphic bokeh). Uniform in area. Returns (x, y)."""
    if blades < 3:
        a = 2.0 * u1 - 1.0
        b = 2.0 * u2 - 1.0
        if a == 0.0 and b == 0.0:
            return 0.0, 0.0
        if a * a > b * b:
            r = a
            phi = 0.25 * math.pi * (b / a)
        else:
            r = b
            phi = 0.5 * math.pi - 0.25 * math.pi * (a / b)
        return r * math.cos(phi) * inv_ratio, r * math.sin(phi)
    corners = float(blades)
    corner = math.floor(u1 * corners)
    u = u1 * corners - corner
    u = math.sqrt(u)
    v = u2 * u
    u = 1.0 - u
    angle = math.pi / corners
    x = (u + v) * math.cos(angle)
    y = (u - v) * math.sin(angle)
    rot = rotation + corner * 2.0 * angle
    cr = math.cos(rot)
    sr = math.sin(rot)
    return (cr * x - sr * y) * inv_ratio, sr * x + cr * y


@kernel
def camera_rays_kernel(ortho, hw, hh, shift_x, shift_y, R, pos, clip_start, clip_end,
                       width, height, px, py, jx, jy, table, aperture, focus, blades,
                       blade_rotation, inv_ratio, lu, lv, pano):
    """Rays through image positions (px + fx, py + fy) (N,), rows top-down, where
    fx = table(jx), fy = table(jy) (engine/pixelfilter.py filter_table; an empty table:
    jx, jy are the positions inside the pixel themselves).
    ortho: orthographic camera (else perspective); hw, hh: the image plane's half extents
    at distance 1 (ortho: world units); R (3,3) camera-to-world rotation (columns: right,
    up, backwards); pos (3,) camera position (re-centred). Blender clips by depth along the
    view axis: clip_start / clip_end are converted to distances along each ray.
    Depth of field (thin lens, Cycles' camera_sample_perspective / _orthographic): with
    aperture > 0 (the lens radius, m) and lu, lv (N,) uniform numbers, the ray starts at
    the lens point aperture * aperture_point(lu, lv) (camera x, y) and passes through the
    pinhole ray's point at depth `focus` (m, along the view axis); perspective clip
    distances keep the pinhole ray's depth scale, as Cycles does. Empty lu / lv or aperture 0: pinhole,
    the arithmetic of the kernel before depth of field (bitwise).
    pano: a panoramic camera's packed parameters (engine/panorama.py Panorama.pack; empty:
    perspective or orthographic): the image position (u, v) = (shift_x + x / width,
    shift_y + 1 - y / height) maps to a direction (panorama_direction), turned by the
    panorama's frame and R; clip distances along the ray (Cycles' camera_sample_panorama);
    outside the lens the ray points along the view axis with distance limit 0 (no light).
    Returns (origins (N,3), unit directions (N,3), distance limits (N,)), float64."""
    n = px.shape[0]
    o = np.empty((n, 3))
    d = np.empty((n, 3))
    tmax = np.empty(n)
    big = 2.0 * max(hw, hh)
    lens = aperture > 0.0 and focus > 0.0
    if pano.shape[0] > 0:
        _panorama_rays(R, pos, clip_start, clip_end, width, height, px, py, jx, jy, table,
                       aperture, focus, blades, blade_rotation, inv_ratio, lu, lv, pano,
                       shift_x, shift_y, o, d, tmax)
        return o, d, tmax
    for i in range(n):
        sx = (px[i] + _filter_position(table, jx[i])) / width * 2.0 - 1.0
        sy = 1.0 - (py[i] + _filter_position(table, jy[i])) / height * 2.0
        x = sx * hw + shift_x * big
        y = sy * hh + shift_y * big
        if ortho:
            scale = 1.0
            for c in range(3):
                o[i, c] = pos[c] + x * R[c, 0] + y * R[c, 1]
                d[i, c] = -R[c, 2]
        else:
            # d = R @ (x, y, -1), normalised
            d0 = x * R[0, 0] + y * R[0, 1] - R[0, 2]
            d1 = x * R[1, 0] + y * R[1, 1] - R[1, 2]
            d2 = x * R[2, 0] + y * R[2, 1] - R[2, 2]
            scale = math.sqrt(d0 * d0 + d1 * d1 + d2 * d2)
            d[i, 0], d[i, 1], d[i, 2] = d0 / scale, d1 / scale, d2 / scale
            for c in range(3):
                o[i, c] = pos[c]
        t_start = clip_start * scale
        t_end = clip_end * scale
        if lens and lu.shape[0] > 0:
            ax, ay = aperture_point(lu[i], lv[i], blades, blade_rotation, inv_ratio)
            ax *= aperture
            ay *= aperture
            # The ray from the lens point (on the camera plane) through the pinhole ray's
            # point on the plane of focus at depth `focus` (camera frame, looking along
            # -z). Perspective: the clip distances keep the pinhole ray's scale, as
            # Cycles' camera_sample_perspective; orthographic: clip depths along the
            # slanted ray (Cycles' orthographic focus is measured from the camera plane
            # too: tests/blender/test_depth_of_field_cycles.py).
            if ortho:
                ex, ey, ez = -ax, -ay, -focus
                lx, ly = x + ax, y + ay
            else:
                ex, ey, ez = x * focus - ax, y * focus - ay, -focus
                lx, ly = ax, ay
            norm = math.sqrt(ex * ex + ey * ey + ez * ez)
            ex, ey, ez = ex / norm, ey / norm, ez / norm
            for c in range(3):
                o[i, c] = pos[c] + lx * R[c, 0] + ly * R[c, 1]
                d[i, c] = ex * R[c, 0] + ey * R[c, 1] + ez * R[c, 2]
            if ortho:
                t_start = clip_start / -ez
                t_end = clip_end / -ez
        for c in range(3):
            o[i, c] = o[i, c] + t_start * d[i, c]
        tmax[i] = t_end - t_start
    return o, d, tmax


@kernel
def _panorama_rays(R, pos, clip_start, clip_end, width, height, px, py, jx, jy, table,
                   aperture, focus, blades, blade_rotation, inv_ratio, lu, lv, pano,
                   shift_x, shift_y, o, d, tmax):
    """camera_rays_kernel's panoramic camera (its docstring), into o, d, tmax."""
    F = pano[P_FRAME:P_FRAME + 9]
    lens = aperture > 0.0 and focus > 0.0 and lu.shape[0] > 0
    for i in range(px.shape[0]):
        u = shift_x + (px[i] + _filter_position(table, jx[i])) / width
        v = shift_y + 1.0 - (py[i] + _filter_position(table, jy[i])) / height
        x, y, z = panorama_direction(pano, u, v)
        norm = math.sqrt(x * x + y * y + z * z)
        if not norm > 0.0:
            for c in range(3):
                o[i, c] = pos[c]
                d[i, c] = -R[c, 2]
            tmax[i] = 0.0
            continue
        x, y, z = x / norm, y / norm, z / norm
        lx, ly, lz = 0.0, 0.0, 0.0
        if lens:
            # Cycles: the lens in the plane across the direction, U from the frame's x.
            ax, ay = aperture_point(lu[i], lv[i], blades, blade_rotation, inv_ratio)
            ax *= aperture
            ay *= aperture
            ux, uy, uz = 1.0 - x * x, -x * y, -x * z
            un = math.sqrt(ux * ux + uy * uy + uz * uz)
            if un < 1e-12:  # looking along the frame's x: any axis across it
                ux, uy, uz, un = 0.0, 1.0, 0.0, 1.0
            ux, uy, uz = ux / un, uy / un, uz / un
            vx, vy, vz = y * uz - z * uy, z * ux - x * uz, x * uy - y * ux
            lx, ly, lz = ux * ax + vx * ay, uy * ax + vy * ay, uz * ax + vz * ay
            ex, ey, ez = x * focus - lx, y * focus - ly, z * focus - lz
            en = math.sqrt(ex * ex + ey * ey + ez * ez)
            x, y, z = ex / en, ey / en, ez / en
        # frame -> camera object axes -> world
        cx = F[0] * x + F[1] * y + F[2] * z
        cy = F[3] * x + F[4] * y + F[5] * z
        cz = F[6] * x + F[7] * y + F[8] * z
        qx = F[0] * lx + F[1] * ly + F[2] * lz
        qy = F[3] * lx + F[4] * ly + F[5] * lz
        qz = F[6] * lx + F[7] * ly + F[8] * lz
        for c in range(3):
            d[i, c] = cx * R[c, 0] + cy * R[c, 1] + cz * R[c, 2]
            o[i, c] = pos[c] + qx * R[c, 0] + qy * R[c, 1] + qz * R[c, 2]
        dn = math.sqrt(d[i, 0] * d[i, 0] + d[i, 1] * d[i, 1] + d[i, 2] * d[i, 2])
        for c in range(3):
            d[i, c] = d[i, c] / dn
            o[i, c] = o[i, c] + clip_start * d[i, c]
        tmax[i] = clip_end - clip_start


@kernel
def chunk_samples(start, spp, m, cell_order, jitter, rw, x0, y0, pix, sub, px, py, jx, jy):
    """Camera samples start + k (sample = pixel * spp + sub-sample) of a chunk, k < N, in
    one pass (integrator._render_chunk): pix, sub (N,) int64; the pixel's column and row
    px = x0 + pix mod rw, py = y0 + pix div rw (N,) int64; the jittered position inside
    the pixel jx = (cell mod m + jitter[0]) / m, jy = (cell div m + jitter[1]) / m (N,)
    float64 of the stratified cell cell = cell_order[sub mod m^2] (m x m grid, visited in
    the scrambled order cell_order (m^2,) int64), jitter (2, N) uniform numbers. The same
    integer and floating-point operations as the numpy stage it replaced."""
    cells = m * m
    n = pix.shape[0]
    if n == 0:
        return
    # m a power of two: b mod m^2, cell mod m and cell div m by masks and shifts (all
    # non-negative: the same integers), not three integer divisions a sample.
    pow2 = m > 0 and (m & (m - 1)) == 0
    sh = pow2_shift(m)
    # Counters carried from sample to sample instead of six integer divisions each.
    p = start // spp
    b = start % spp
    col = p % rw
    row = p // rw
    for k in range(n):
        pix[k] = p
        sub[k] = b
        if pow2:
            cell = cell_order[b & (cells - 1)]
            jx[k] = ((cell & (m - 1)) + jitter[0, k]) / m
            jy[k] = ((cell >> sh) + jitter[1, k]) / m
        else:
            cell = cell_order[b % cells]
            jx[k] = (cell % m + jitter[0, k]) / m
            jy[k] = (cell // m + jitter[1, k]) / m
        px[k] = x0 + col
        py[k] = y0 + row
        b += 1
        if b == spp:
            b = 0
            p += 1
            col += 1
            if col == rw:
                col = 0
                row += 1


@register_warm_up
def _warm_up():
    i64 = np.empty(4, np.int64)
    chunk_samples(0, 4, 2, np.arange(4), np.full((2, 4), 0.5), 2, 0, 0, i64, i64.copy(),
                  i64.copy(), i64.copy(), np.empty(4), np.empty(4))
    R = np.eye(3)
    pos = np.zeros(3)
    for ortho in (False, True):
        for px in (np.arange(4), np.arange(4.0)):  # render_camera's ints, effects' floats
            for table in (np.empty(0), np.linspace(-1.0, 2.0, 8)):
                for lu in (np.empty(0), np.full(4, 0.3)):  # pinhole, thin lens
                    camera_rays_kernel(ortho, 0.5, 0.4, 0.0, 0.0, R, pos, 0.1, 100.0, 4, 3,
                                       px, px, np.full(4, 0.5), np.full(4, 0.5), table,
                                       0.01 * lu.shape[0], 2.0, 0, 0.0, 1.0, lu, lu,
                                       np.empty(0) if ortho else _WARM_PANO)


_WARM_PANO = Panorama().pack(4, 3, "AUTO")

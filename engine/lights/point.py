"""Point light (Blender's Point, optionally with a radius): intensity P/(4 pi) W/sr.

With a radius r its radiance is I / (pi r^2) (Cycles' eval_fac x strength) on one of two
shapes, as Blender's "Soft Falloff" (Light.soft_falloff) picks (Cycles'
kernel/light/point.h; `is_sphere` = not use_soft_falloff):
- Soft Falloff on (Blender's default): a disk of radius r through the centre facing the
  shading point, both for shadow rays and for rays that meet it. A point at distance d
  receives I / (d^2 + r^2) face-on: the light fades where it nearly touches a surface.
- Soft Falloff off: a sphere of radius r. Shadow rays sample the cone of directions it
  subtends uniformly (pdf 1 / (2 pi (1 - cos a)), sin a = r / d), rays meet the sphere;
  a point receives I / d^2 face-on, as from a point, however close (from inside the
  sphere: cosine-distributed directions, pi L).
Photons leave the sphere's surface cosine-distributed in both cases; with Soft Falloff
their power at the first hit takes d^2 / (d^2 + r^2), so that they too give I / (d^2 +
r^2) (engine/photons.py soft_falloff_sources: the two differ within a few radii of the
light, which is where a lamp shade lies: 1.19x Cycles without it)."""
from __future__ import annotations

import math

import numpy as np

from ..jit import kernel, register_warm_up
from ..sampling import dot
from .emission import (cosine_hemisphere, f64, emit_uniform, put, to_world, aim_direction,
                       uniform_sphere, pick, concentric_disk)
from ..scene import POINT
from ..ies import direction_from_angles, ies_factor, ies_factors
from . import packing as pk
from .base import Light


# The IES photons' direction cells: cos v and h (PointLight._prepare_ies).
IES_NC, IES_NH = 96, 96


def ies_factors_rows(tab, w, out):
    """ies.ies_factors for the packed profile tab along rows of w (N,3)."""
    ies_factors(tab, 0, np.ascontiguousarray(w, np.float64), out)


class PointLight(Light):
    kind = POINT
    ies = None  # the packed IES profile (engine/ies.py), None without one

    @classmethod
    def from_scene(cls, light, geo, common):
        kw = cls.scene_params(light, geo, common)
        kw.update(cls.extra_params(light))
        intensity = light.power * light.color / (4.0 * math.pi)
        kw.update(intensity=intensity, flux=light.flux, photon_flux=light.flux,
                  soft_falloff=bool(light.soft_falloff), ies=None)
        out = cls(light.name, **kw)
        if light.ies_profile is not None:
            out._prepare_ies(light)
        return out

    def _prepare_ies(self, light):
        """The IES profile (engine/ies.py) packed in the lamp's frame (rows: its local X,
        Y, Z in world space: the normal's object space of Cycles' default Vector), and
        the photons' direction distribution: IES_NC x IES_NH cells equal in solid angle
        (cos v, h), each drawn in proportion to the mean of f x the spot mask at 2 x 2
        points in it (at least 1e-4 of the largest mean, so that every direction can be
        drawn: the photons' power f / pdf is then unbiased). photon_flux becomes
        intensity x the integral of f x mask (the cells' sum): what the photons carry."""
        lamp = np.stack([light.axis_u, light.axis_v, -light.direction])
        self.ies = np.ascontiguousarray(light.ies_profile.packed(lamp))
        self.ies_inverse = np.ascontiguousarray(np.linalg.inv(lamp))
        nc, nh = IES_NC, IES_NH
        cz = (np.arange(2 * nc) + 0.5) / (2 * nc) * 2.0 - 1.0  # cos v in [-1, 1]
        h = (np.arange(2 * nh) + 0.5) / (2 * nh) * 2.0 * math.pi
        C, Hh = np.meshgrid(cz, h, indexing="ij")
        local = direction_from_angles(Hh.ravel(), np.arccos(np.clip(C.ravel(), -1.0, 1.0)))
        world = local @ self.ies_inverse.T
        world /= np.linalg.norm(world, axis=1)[:, None]
        f = np.empty(len(world))
        ies_factors(self.ies, 0, np.ascontiguousarray(world), f)
        mask = self._falloff_plain(world)
        if mask is not None:
            f = f * mask
        mean = f.reshape(nc, 2, nh, 2).mean(axis=(1, 3))  # (nc, nh) over cos v, h cells
        cell_omega = 4.0 * math.pi / (nc * nh)
        integral = float(mean.sum() * cell_omega)
        weight = np.maximum(mean, 1e-4 * max(float(mean.max()), 1e-300)).ravel()
        prob = weight / weight.sum()
        cdf = np.cumsum(prob)
        cdf[-1] = 1.0
        self.ies_cdf = cdf
        self.ies_pdf = prob / cell_omega  # solid-angle pdf (1/sr) in each cell
        self.photon_flux = self.intensity * integral

    @staticmethod
    def extra_params(light) -> dict:
        return {}

    @property
    def has_size(self) -> bool:
        return self.radius > 0

    @property
    def has_surface(self) -> bool:
        return self.radius > 0

    def pack(self, row) -> int:
        """Write the kernel parameters (engine/lights/packing.py); returns the kind code."""
        row[pk.POS:pk.POS + 3] = self.pos
        row[pk.RGB:pk.RGB + 3] = self.intensity
        row[pk.RADIUS] = self.radius
        row[pk.SPHERE] = 1.0 if self.is_sphere else 0.0
        if self.ies is not None:
            row[pk.IES:pk.IES + len(self.ies)] = self.ies
        return pk.CODE_POINT

    @property
    def is_sphere(self) -> bool:
        """True: a sphere of the light's radius (Soft Falloff off), not the facing disk."""
        return self.radius > 0 and not getattr(self, "soft_falloff", True)

    def _falloff_plain(self, axis):
        """The directional factor without the IES profile: None (1) for a point light,
        the spot's mask for a spot."""
        return None

    def _emit(self, aim, aimed, key, first, n, count, out, start):
        """Natural photons of an IES lamp are drawn from its profile (emit_ies); aimed
        ones as the plain light's, their power times the profile (_weigh_ies)."""
        if self.ies is not None and not aimed:
            frame, cos_half, width = self._spot_params()
            return emit_ies(self.ies, self.ies_inverse, self.ies_cdf, self.ies_pdf,
                            IES_NC, IES_NH, f64(self.pos), float(self.radius),
                            f64(self.intensity), frame, cos_half, width, key, first, n,
                            float(count), *out.arrays, start)
        j = self._emit_plain(aim, aimed, key, first, n, count, out, start)
        if self.ies is not None:
            j = self._weigh_ies(out, start, j)
        return j

    def _spot_params(self):
        """(frame (3,3), cos_half, width) of spot_mask_at; cos_half -2: no mask."""
        return np.eye(3), -2.0, 0.0

    def _weigh_ies(self, out, start, j):
        """Rows start .. j - 1 of out times the profile along their direction, those
        left without power removed (compacted as put does); returns the next free row."""
        o32, d32, d, power, slot = out.arrays
        g = np.empty(j - start)
        ies_factors_rows(self.ies, d[start:j], g)
        power[start:j] *= g[:, None]
        keep = start + np.flatnonzero(np.any(power[start:j] > 0, axis=1))
        m = start + len(keep)
        for a in (o32, d32, d, power, slot):
            a[start:m] = a[keep]
        return m

    def _emit_plain(self, aim, aimed, key, first, n, count, out, start):
        return emit_point(f64(self.pos), float(self.radius), f64(self.flux),
                          *aim.arrays, aimed, key, first, n, float(count), *out.arrays, start)

    def intersect(self, o, d, tmax):
        """A light with a radius, met by rays (o, d (N,3), tmax (N,)): (mask, t, radiance
        I / (pi r^2) x the spot mask). With Soft Falloff it is a disk of radius r through
        its centre facing the ray's origin: the shape its shadow rays sample
        (directlight.sample_lights) and Cycles' point_light_intersect. (A sphere met by
        the continuation had a rim of directions, relative width ~ r^2 / distance^2, that
        the disk's shadow rays never pick: those paths took the full light without
        multiple importance sampling, single-sample sparkles on glossy surfaces.) Without
        it, the sphere (ray_sphere_intersect); a spot's mask is then read along the ray,
        and only from outside the sphere (Cycles' spot_light_sample_from_intersection)."""
        if self.radius <= 0:
            return super().intersect(o, d, tmax)
        n = len(o)
        if self.is_sphere:
            rel = o - self.pos
            t = sphere_hit(rel, d, self.radius)
            mask = t < tmax
            inside = np.einsum("ij,ij->i", rel, rel) <= self.radius ** 2
        else:
            # One compiled pass (intersect_disk), the numpy stage's arithmetic.
            tm = f64(np.broadcast_to(np.asarray(tmax, np.float64), (n,)))
            mask, t = np.empty(n, np.bool_), np.empty(n)
            intersect_disk(f64(o), f64(d), tm, f64(self.pos), float(self.radius ** 2), mask, t)
            inside = np.zeros(n, bool)
        L = np.broadcast_to(self.intensity / (math.pi * self.radius ** 2), (n, 3))
        f = self._falloff_plain(-d)
        if f is not None:
            L = L * np.where(inside, 1.0, f)[:, None]
        if self.ies is not None:
            # The profile along the ray (towards its origin: -d), the disk's and the
            # sphere's alike, as the shadow rays read it (directlight.py).
            g = np.empty(n)
            ies_factors_rows(self.ies, -d, g)
            L = L * g[:, None]
        return mask, t, L


@kernel
def spot_mask_at(frame, cos_half, width, w0, w1, w2):
    """scene.spot_mask(spot_cone_cos(w, frame), ...) for one direction w leaving the light:
    Cycles' smoothstep of the cosine to the (scaled) cone's axis."""
    l0 = frame[0, 0] * w0 + frame[0, 1] * w1 + frame[0, 2] * w2
    l1 = frame[1, 0] * w0 + frame[1, 1] * w1 + frame[1, 2] * w2
    l2 = frame[2, 0] * w0 + frame[2, 1] * w1 + frame[2, 2] * w2
    x = l2 / max(math.sqrt(l0 * l0 + l1 * l1 + l2 * l2), 1e-300) - cos_half
    if width <= 0:
        return 1.0 if x > 0 else 0.0
    f = min(max(x / width, 0.0), 1.0)
    return f * f * (3.0 - 2.0 * f)


@kernel
def intersect_disk(o, d, tmax, pos, radius2, mask, t):
    """PointLight.intersect with Soft Falloff for rays o, d (N,3) up to tmax (N,): the
    disk of squared radius radius2 through pos facing each ray's origin. Writes mask (N,)
    (the ray meets the disk before tmax) and t (N,) (the distance to the disk's plane
    along the ray, inf where the ray does not travel towards the centre). The numpy
    stage's arithmetic operation for operation (np.linalg.norm sums x^2 + y^2 then + z^2,
    np.einsum's dot products (x + z) + y; np.maximum keeps a NaN), so the same bits
    (tests/test_soft_falloff.py)."""
    for i in range(o.shape[0]):
        r0, r1, r2 = o[i, 0] - pos[0], o[i, 1] - pos[1], o[i, 2] - pos[2]
        dist = math.sqrt((r0 * r0 + r1 * r1) + r2 * r2)
        ds = 1e-300 if dist < 1e-300 else dist
        a0, a1, a2 = r0 / ds, r1 / ds, r2 / ds
        d0, d1, d2 = d[i, 0], d[i, 1], d[i, 2]
        toward = -((d0 * a0 + d2 * a2) + d1 * a1)
        front = toward > 1e-12
        ti = dist / (toward if front else 1.0)
        h0, h1, h2 = ti * d0 + r0, ti * d1 + r1, ti * d2 + r2
        mask[i] = (front and dist > 0 and ti < tmax[i]
                   and (h0 * h0 + h2 * h2) + h1 * h1 <= radius2)
        t[i] = ti if front else np.inf


@register_warm_up
def _warm_up():
    one = np.ones((1, 3))
    intersect_disk(one, -one, np.ones(1), np.zeros(3), 0.25, np.empty(1, np.bool_),
                   np.empty(1))


def sphere_light_pdf(light, o, d, ns):
    """Solid-angle pdf (N,) of a sphere light's shadow rays (directlight's
    _sphere_light_sample) for directions d (N,3) from points o (N,3): uniform over the
    cone the sphere subtends from outside (1 / (2 pi (1 - cos a))), cos / pi round the
    shading normals ns (N,3) from inside (Cycles' sphere_light_pdf). Directions that miss
    the sphere get the cone's pdf too: callers ask only for rays that met it."""
    rel = o - light.pos
    x = light.radius ** 2 / np.maximum(np.einsum("ij,ij->i", rel, rel), 1e-300)
    outside = x < 1.0
    xo = np.minimum(x, 1.0)
    one_minus_cos = xo / (1.0 + np.sqrt(1.0 - xo))
    cone = 1.0 / (2.0 * math.pi * np.maximum(one_minus_cos, 1e-300))
    if ns is None:
        return cone
    return np.where(outside, cone, np.maximum(dot(d, ns), 0.0) / math.pi)


def sphere_hit(rel, d, radius):
    """Distance (N,) along unit directions d (N,3) from points rel (N,3, relative to a
    sphere's centre) to the sphere of `radius` (the far side from inside), inf where the
    ray misses it or it lies behind."""
    b = dot(rel, d)
    c = np.einsum("ij,ij->i", rel, rel) - radius * radius
    disc = b * b - c
    root = np.sqrt(np.maximum(disc, 0.0))
    near, far = -b - root, -b + root
    t = np.where(near > 0, near, far)
    return np.where((disc >= 0) & (t > 0), t, np.inf)


@kernel
def emit_point(pos, radius, flux, centers, radii, probs, cdf, aimed, key, first, n, count,
               o32, d32, d, power, slot, start):
    """Photons of a point light of flux `flux` (3,) W, radius `radius` (a sphere emitting
    cosine-distributed from its surface: each point's radiance is the same): uniform over
    the sphere of directions without radius. aimed: directions aimed at the spheres
    (centers, radii; emission.aim_direction), weighted by natural pdf / aimed pdf.
    Dimensions: 0, 1 the point on the sphere (or the direction), 2, 3 the direction;
    aimed: 0 the target, 1, 2 the point, 3, 4 the direction."""
    j = start
    f0, f1, f2 = flux[0] / count, flux[1] / count, flux[2] / count
    for i in range(n):
        s = first + i
        o0, o1, o2 = pos[0], pos[1], pos[2]
        a0 = a1 = a2 = 0.0
        w = 1.0
        if not aimed:
            a0, a1, a2 = uniform_sphere(emit_uniform(key, s, 0), emit_uniform(key, s, 1))
            if radius > 0:
                o0, o1, o2 = pos[0] + radius * a0, pos[1] + radius * a1, pos[2] + radius * a2
                l0, l1, l2 = cosine_hemisphere(emit_uniform(key, s, 2), emit_uniform(key, s, 3))
                d0, d1, d2 = to_world(l0, l1, l2, a0, a1, a2)
            else:
                d0, d1, d2 = a0, a1, a2
        else:
            if radius > 0:
                a0, a1, a2 = uniform_sphere(emit_uniform(key, s, 1), emit_uniform(key, s, 2))
                o0, o1, o2 = pos[0] + radius * a0, pos[1] + radius * a1, pos[2] + radius * a2
            d0, d1, d2, pdf_aim = aim_direction(centers, radii, probs, cdf, o0, o1, o2,
                                                emit_uniform(key, s, 0), emit_uniform(key, s, 3),
                                                emit_uniform(key, s, 4))
            if radius > 0:
                pdf_nat = max(d0 * a0 + d1 * a1 + d2 * a2, 0.0) / math.pi
            else:
                pdf_nat = 1.0 / (4.0 * math.pi)
            w = pdf_nat / pdf_aim
        j = put(o32, d32, d, power, slot, j, o0, o1, o2, d0, d1, d2, f0 * w, f1 * w, f2 * w, s)
    return j


@kernel
def emit_ies(tab, inverse, cdf, pdf, nc, nh, pos, radius, intensity, frame, cos_half, width,
             key, first, n, count, o32, d32, d, power, slot, start):
    """Photons of a point / spot lamp with an IES profile (tab: ies.IESProfile.packed in
    the lamp's frame; inverse (3,3) lamp -> world): a cell of the (cos v, h) grid of nc x
    nh cells picked by cdf, the direction uniform in it (pdf (nc nh,) its solid-angle
    pdf), power intensity x f x the spot mask (cos_half -2: none) / (count x pdf); with a
    radius each leaves from a disk of that radius across its direction (as a spot's).
    Dimensions: 0 the cell, 1, 2 the direction in it, 3, 4 the disk."""
    j = start
    for i in range(n):
        s = first + i
        c = pick(cdf, emit_uniform(key, s, 0))
        ic = c // nh
        ih = c - ic * nh
        cz = -1.0 + 2.0 * (ic + emit_uniform(key, s, 1)) / nc
        h = 2.0 * math.pi * (ih + emit_uniform(key, s, 2)) / nh
        sv = math.sqrt(max(1.0 - cz * cz, 0.0))
        # svm_node_ies inverted: v = acos(-z), h = atan2(x, y) + pi; cz = cos v.
        l0, l1, l2 = sv * math.sin(h - math.pi), sv * math.cos(h - math.pi), -cz
        d0 = inverse[0, 0] * l0 + inverse[0, 1] * l1 + inverse[0, 2] * l2
        d1 = inverse[1, 0] * l0 + inverse[1, 1] * l1 + inverse[1, 2] * l2
        d2 = inverse[2, 0] * l0 + inverse[2, 1] * l1 + inverse[2, 2] * l2
        nd = math.sqrt(d0 * d0 + d1 * d1 + d2 * d2)
        d0, d1, d2 = d0 / nd, d1 / nd, d2 / nd
        f = ies_factor(tab, 0, d0, d1, d2)
        if cos_half > -1.5:
            f *= spot_mask_at(frame, cos_half, width, d0, d1, d2)
        w = f / (count * pdf[c])
        o0, o1, o2 = pos[0], pos[1], pos[2]
        if radius > 0:
            x, y = concentric_disk(emit_uniform(key, s, 3), emit_uniform(key, s, 4))
            t0, t1, t2 = to_world(x, y, 0.0, d0, d1, d2)
            o0, o1, o2 = o0 + radius * t0, o1 + radius * t1, o2 + radius * t2
        j = put(o32, d32, d, power, slot, j, o0, o1, o2, d0, d1, d2, intensity[0] * w,
                intensity[1] * w, intensity[2] * w, s)
    return j


@register_warm_up
def _warm_up_ies():
    from ..ies import IESProfile
    tab = IESProfile(np.radians([0.0, 360.0]), np.radians([0.0, 90.0, 180.0]),
                     np.ones((2, 3))).packed(np.eye(3))
    cdf = np.array([0.5, 1.0])
    buf = (np.empty((1, 3), np.float32), np.empty((1, 3), np.float32), np.empty((1, 3)),
           np.empty((1, 3)), np.empty(1, np.int64))
    emit_ies(tab, np.eye(3), cdf, np.ones(2), 1, 2, np.zeros(3), 0.0, np.ones(3), np.eye(3),
             -2.0, 0.0, np.uint64(1), 0, 1, 1.0, *buf, 0)

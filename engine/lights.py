"""Lights in Cycles units: sampling for shadow rays, photon emission, visibility in mirrors.

Conventions (docs/units.md; docs/design.md, Units (Cycles)): a point light of power P has
intensity P/(4*pi) W/sr; a spot is that point light masked by Cycles' smoothstep cone; an area light
emits one-sided uniform radiance P/(pi*A) along its -Z axis; a sun gives irradiance
`strength` W/m^2; emissive meshes emit their radiance from both sides; a non-black
background is a uniform environment.
"""
from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from .geometry import Geometry, MaterialTable, emissive_triangles
from .rayoffset import (G64, embree_plane_error, origin_offset, tilt_error,
                        triangle_point_error, ulp32)
from .sampling import (concentric_disk, cosine_hemisphere, dot, luminance, max3,
                       offset_origin,
                       orthonormal_basis, to_world, uniform_cone, uniform_sphere,
                       uniform_triangle)
from .scene import (AREA, DISK, POINT, SPOT, SUN, Scene, spot_bounding_cos, spot_cone_cos,
                    spot_mask, spread_attenuation)

MESH, WORLD = "MESH", "WORLD"


@dataclass
class LightSample:
    wi: np.ndarray      # (N,3) unit direction from the shading point to the light sample
    dist: np.ndarray    # (N,) distance to the sample (inf for sun / world)
    E: np.ndarray       # (N,3) irradiance estimate ignoring visibility (cos at receiver in)
    y: np.ndarray | None = None        # (N,3) the sampled point; None at infinity
    ny: np.ndarray | None = None       # (N,3) unit normal of the emitting surface at y
    end_gap: np.ndarray | None = None  # (N,) rounding-error bound of y along ny: a shadow
                                       # ray must end at least this far before the surface


class PreparedLight:
    """One light, re-centred, with everything sampling needs precomputed."""

    def __init__(self, name, kind, **kw):
        self.name = name
        self.kind = kind
        self.__dict__.update(kw)

    # ------------------------------------------------------------------ properties
    @property
    def has_size(self) -> bool:
        """Needs several shadow samples (soft shadows)."""
        if self.kind in (POINT, SPOT):
            return self.radius > 0
        if self.kind == SUN:
            return self.cos_half_angle < 1.0
        return True

    def _spot(self, w):
        """Spot mask for world directions w (N,3) leaving the light; the cone is
        stretched by the light object's scale (Light.spot_frame)."""
        return spot_mask(spot_cone_cos(w, self.spot_frame), self.spot_size, self.spot_blend)

    # ------------------------------------------------------------------ points on lights
    def _area_point(self, u1, u2):
        """Uniform points on an area light's rectangle or ellipse."""
        if self.shape == DISK:
            x, yy = concentric_disk(u1, u2)
            x, yy = x * self.size_x / 2, yy * self.size_y / 2
        else:
            x, yy = (u1 - 0.5) * self.size_x, (u2 - 0.5) * self.size_y
        # du, dv: the dual basis of (u, v) in the light's plane (= u, v unless sheared),
        # so that p.u and p.v span the region the intersection test accepts.
        return self.pos + x[:, None] * self.du + yy[:, None] * self.dv

    def _mesh_point(self, rng, u1, u2):
        """(triangle index, point, barycentrics b1, b2) on the emissive triangles, chosen
        by area x brightness."""
        tri = np.searchsorted(self.cdf, rng.random(len(u1)), side="right").clip(0, len(self.cdf) - 1)
        b1, b2 = uniform_triangle(u1, u2)
        return tri, self.v0[tri] + b1[:, None] * self.e1[tri] + b2[:, None] * self.e2[tri], b1, b2

    def _mesh_error(self, tri, b1, b2, y):
        """(N,3) rounding-error bound of points y on emissive triangles (engine/rayoffset.py)."""
        return triangle_point_error(self.v0[tri], self.e1[tri], self.e2[tri], self.round32[tri],
                                    b1, b2, y)

    def _mesh_offset(self, tri, b1, b2, y):
        """(N,) distance along the normal that takes a ray leaving y clear of its triangle
        (engine/rayoffset.py)."""
        return origin_offset(self._mesh_error(tri, b1, b2, y), self.v0[tri], self.e1[tri],
                             self.e2[tri], self.tri_ng[tri], y, self.tilt32[tri])

    # ------------------------------------------------------------------ shadow rays
    def sample(self, p, ns, ng, rng, uv=None) -> LightSample:
        """One light sample per point; uv = optional stratified (u1, u2) in [0,1)."""
        n = len(p)
        u1, u2 = uv if uv is not None else (rng.random(n), rng.random(n))
        if self.kind == SUN:
            local = uniform_cone(u1, u2, self.cos_half_angle)
            wi = to_world(local, np.broadcast_to(-self.dir, (n, 3)))
            cos_r = np.maximum(dot(wi, ns), 0.0) * (dot(wi, ng) > 0)
            return LightSample(wi, np.full(n, np.inf), self.irradiance[None, :] * cos_r[:, None])
        if self.kind == WORLD:
            wi = to_world(cosine_hemisphere(u1, u2), ns)
            ok = dot(wi, ng) > 0
            E = math.pi * self.radiance[None, :] * ok[:, None]
            return LightSample(wi, np.full(n, np.inf), E)
        if self.kind == MESH:
            tri, y, b1, b2 = self._mesh_point(rng, u1, u2)
            ny = self.tri_ng[tri]
            # The ray must end before the emitting triangle as Embree (float32, from the
            # shading point) places it: the point's own error plus Embree's plane error.
            err = self._mesh_error(tri, b1, b2, y)
            an = np.abs(ny)
            gap = (an[:, 0] * err[:, 0] + an[:, 1] * err[:, 1] + an[:, 2] * err[:, 2]
                   + embree_plane_error(self.v0[tri], self.e1[tri], self.e2[tri], ny, p)
                   + tilt_error(self.v0[tri], self.e1[tri], self.e2[tri], self.tilt32[tri], p))
            return self._finish_area(p, ns, ng, y, ny,
                                     self.tri_L[tri] * (self.tri_area[tri] / self.prob[tri])[:, None],
                                     two_sided=True, gap=gap)
        if self.kind == AREA:
            if (self.spread < math.pi and self.shape != DISK and np.allclose(self.du, self.u)
                    and np.allclose(self.dv, self.v)):  # a sheared light samples it whole
                return self._sample_spread_rect(p, ns, ng, u1, u2)
            y = self._area_point(u1, u2)
            y = self._area_point(u1, u2)
            ls = self._finish_area(p, ns, ng, y, np.broadcast_to(self.dir, (n, 3)),
                                   np.broadcast_to(self.radiance * self.area, (n, 3)),
                                   two_sided=False, gap=self._area_gap(y))
            if self.spread < math.pi:
                ls.E = ls.E * spread_attenuation(dot(-ls.wi, self.dir), self.spread)[:, None]
            return ls
        # POINT / SPOT, optionally with a radius: sample the disk facing the point.
        to_p = p - self.pos
        d_c = np.linalg.norm(to_p, axis=1)
        axis = to_p / np.maximum(d_c, 1e-300)[:, None]
        if self.radius > 0:
            x, yy = concentric_disk(u1, u2)
            t, b = orthonormal_basis(axis)
            y = self.pos + self.radius * (x[:, None] * t + yy[:, None] * b)
        else:
            y = np.broadcast_to(self.pos, (n, 3))
        w = y - p
        dist = np.linalg.norm(w, axis=1)
        wi = w / np.maximum(dist, 1e-300)[:, None]
        cos_r = np.maximum(dot(wi, ns), 0.0) * (dot(wi, ng) > 0)
        cos_l = np.maximum(dot(-wi, axis), 0.0) if self.radius > 0 else 1.0
        d2 = np.maximum(dist * dist, _min_dist2(p, y))
        E = self.intensity[None, :] * (cos_r * cos_l / d2)[:, None]
        if self.kind == SPOT:
            E = E * self._spot(axis)[:, None]
        return LightSample(wi, dist, E, y=y)

    def _sample_spread_rect(self, p, ns, ng, u1, u2):
        """A rectangle with a narrow spread lights p only from the part of it within
        tan(h) x (p's height over its plane) of p's foot point: sample that part only, as
        Cycles does (kernel/light/area.h, area_light_spread_clamp_light); the rest has
        f = 0. Same expectation as sampling the whole rectangle, far less noise."""
        rel = p - self.pos
        height = dot(rel, self.dir)             # > 0 in front of the light (dir: emission)
        reach = np.maximum(height, 0.0) * math.tan(0.5 * self.spread)
        pu, pv = dot(rel, self.u), dot(rel, self.v)
        hx, hy = self.size_x / 2, self.size_y / 2
        x0, x1 = np.maximum(pu - reach, -hx), np.minimum(pu + reach, hx)
        y0, y1 = np.maximum(pv - reach, -hy), np.minimum(pv + reach, hy)
        wx, wy = np.maximum(x1 - x0, 0.0), np.maximum(y1 - y0, 0.0)
        x = x0 + u1 * wx
        yy = y0 + u2 * wy
        y = self.pos + x[:, None] * self.u + yy[:, None] * self.v
        area = (wx * wy)[:, None]               # the sampled part: pdf 1 / area
        ls = self._finish_area(p, ns, ng, y, np.broadcast_to(self.dir, (len(p), 3)),
                               self.radiance[None, :] * area, two_sided=False,
                               gap=self._area_gap(y))
        ls.E = ls.E * spread_attenuation(dot(-ls.wi, self.dir), self.spread)[:, None]
        return ls

    def _area_gap(self, y):
        """How far before an area light's plane a shadow ray to its point y must end: y is
        pos + x u + y v in float64, then rounded to float32 as a ray end."""
        err = G64 * (np.abs(self.pos) + np.abs(y - self.pos)) + ulp32(y)
        an = np.abs(self.dir)
        return an[0] * err[:, 0] + an[1] * err[:, 1] + an[2] * err[:, 2]

    def _finish_area(self, p, ns, ng, y, ny, L_times_area, two_sided, gap):
        w = y - p
        dist = np.linalg.norm(w, axis=1)
        wi = w / np.maximum(dist, 1e-300)[:, None]
        cos_r = np.maximum(dot(wi, ns), 0.0) * (dot(wi, ng) > 0)
        cos_l = dot(-wi, ny)
        cos_l = np.abs(cos_l) if two_sided else np.maximum(cos_l, 0.0)
        d2 = np.maximum(dist * dist, _min_dist2(p, y))
        return LightSample(wi, dist, L_times_area * (cos_r * cos_l / d2)[:, None],
                           y=y, ny=ny, end_gap=gap)

    # ------------------------------------------------------------------ photons
    def emit(self, n: int, rng):
        """n photons: origins, unit directions, RGB power (W each); sum of power = flux."""
        u1, u2, u3, u4 = (rng.random(n) for _ in range(4))
        if self.kind in (SUN, WORLD):
            if self.kind == SUN:
                local = uniform_cone(u1, u2, self.cos_half_angle)
                d = to_world(local, np.broadcast_to(self.dir, (n, 3)))
            else:
                d = uniform_sphere(u1, u2)
            x, yy = concentric_disk(u3, u4)
            t, b = orthonormal_basis(d)
            o = (self.center - 2.0 * self.scene_radius * d
                 + self.scene_radius * (x[:, None] * t + yy[:, None] * b))
            return o, d, np.broadcast_to(self.photon_flux / n, (n, 3)).copy()
        if self.kind == MESH:
            tri, o, b1, b2 = self._mesh_point(rng, u1, u2)
            side = np.where(rng.random(n) < 0.5, 1.0, -1.0)[:, None]
            nrm = self.tri_ng[tri] * side
            d = to_world(cosine_hemisphere(u3, u4), nrm)
            power = (2.0 * math.pi * self.tri_area[tri] / (self.prob[tri] * n))[:, None] * self.tri_L[tri]
            # Leave the emitting surface: from a point on the triangle itself, Embree can
            # report the triangle again at t ~ 0 and the photon lands on its own emitter,
            # from the wrong side (measured: a third of a furnace room's photons).
            return offset_origin(o, nrm, d, self._mesh_offset(tri, b1, b2, o)), d, power
        if self.kind == AREA:
            o = self._area_point(u1, u2)
            if self.spread < math.pi:
                # Cosine-distributed inside the spread cone (a disk of radius sin h under
                # the hemisphere): pdf cos a / (pi sin^2 h); the radiance's cos a f(a) / pi
                # over that pdf leaves the weight f(a) sin^2 h (mean 1: flux kept).
                sin_h = math.sin(0.5 * self.spread)
                x, yy = concentric_disk(u3, u4)
                x, yy = x * sin_h, yy * sin_h
                local = np.stack([x, yy, np.sqrt(np.maximum(1.0 - x * x - yy * yy, 0.0))], 1)
                d = to_world(local, np.broadcast_to(self.dir, (n, 3)))
                w = spread_attenuation(local[:, 2], self.spread) * sin_h * sin_h
                return o, d, (self.flux / n)[None, :] * w[:, None]
            d = to_world(cosine_hemisphere(u3, u4), np.broadcast_to(self.dir, (n, 3)))
            return o, d, np.broadcast_to(self.flux / n, (n, 3)).copy()
        if self.kind == SPOT:
            cos_bound = self.spot_cos_bound  # holds the whole (scaled) cone
            local = uniform_cone(u1, u2, cos_bound)
            d = to_world(local, np.broadcast_to(self.dir, (n, 3)))
            solid = 2.0 * math.pi * (1.0 - cos_bound)
            mask = self._spot(d)
            power = self.intensity[None, :] * (mask * solid / n)[:, None]
            o = np.broadcast_to(self.pos, (n, 3)).copy()
            if self.radius > 0:
                x, yy = concentric_disk(u3, u4)
                t, b = orthonormal_basis(d)
                o = o + self.radius * (x[:, None] * t + yy[:, None] * b)
            return o, d, power
        # POINT
        if self.radius > 0:
            s = uniform_sphere(u1, u2)
            o = self.pos + self.radius * s
            d = to_world(cosine_hemisphere(u3, u4), s)
        else:
            o = np.broadcast_to(self.pos, (n, 3)).copy()
            d = uniform_sphere(u1, u2)
        return o, d, np.broadcast_to(self.flux / n, (n, 3)).copy()

    # ------------------------------------------------------------------ aimed photons
    def emit_towards(self, n: int, rng, centers: np.ndarray, radii: np.ndarray):
        """n photons aimed at bounding spheres (caustic casters), weighted so the expected
        power arriving anywhere inside the spheres equals that of emit(): power = natural
        power x natural pdf / aimed pdf (POV-Ray-style photon targets)."""
        K = len(centers)
        if K == 0 or n == 0:
            z = np.zeros((0, 3))
            return z, z.copy(), z.copy()
        if self.kind == SPOT and self.radius > 0:
            # A spot's photons leave from a disk round its centre, shifted after their
            # direction is drawn: aim at spheres grown by that radius, or the directions
            # that reach a caster only from the disk's rim are never drawn (caustic lost).
            radii = radii + self.radius
        u1, u2, u3, u4 = (rng.random(n) for _ in range(4))
        if self.kind in (SUN, WORLD):
            if self.kind == SUN:
                d = to_world(uniform_cone(u1, u2, self.cos_half_angle), np.broadcast_to(self.dir, (n, 3)))
            else:
                d = uniform_sphere(u1, u2)
            probs = radii ** 2 / np.sum(radii ** 2)
            j = rng.choice(K, size=n, p=probs)
            x, yy = concentric_disk(u3, u4)
            t, b = orthonormal_basis(d)
            R = self.scene_radius
            start = self.center - 2.0 * R * d  # the natural disk's centre for direction d
            c = centers[j]
            # Centre of caster j's shadow disk in the plane through `start` normal to d.
            c_proj = c - dot(c - start, d)[:, None] * d
            o = c_proj + radii[j][:, None] * (x[:, None] * t + yy[:, None] * b)
            aimed = np.zeros(n)
            for k in range(K):
                ck = centers[k] - dot(centers[k] - start, d)[:, None] * d
                inside = np.linalg.norm(o - ck, axis=1) <= radii[k]
                aimed += probs[k] * inside / (math.pi * radii[k] ** 2)
            natural = (np.linalg.norm(o - start, axis=1) <= R) / (math.pi * R * R)
            ratio = natural / np.maximum(aimed, 1e-300)
            return o, d, (self.photon_flux / n)[None, :] * ratio[:, None]
        # Origins as the light emits them.
        normal = None
        if self.kind == MESH:
            tri, o, b1, b2 = self._mesh_point(rng, u1, u2)
            normal = self.tri_ng[tri]
            anchor = self.v0.mean(axis=0)
        elif self.kind == AREA:
            o = self._area_point(u1, u2)
            anchor = self.pos
        elif self.kind == POINT and self.radius > 0:
            normal = uniform_sphere(u1, u2)
            o = self.pos + self.radius * normal
            anchor = self.pos
        else:
            o = np.broadcast_to(self.pos, (n, 3)).copy()
            anchor = self.pos
        # Choose a target per photon in proportion to its solid angle seen from the light.
        dist_a = np.linalg.norm(centers - anchor, axis=1)
        sin_a = np.clip(radii / np.maximum(dist_a, 1e-300), 0.0, 1.0)
        omega_a = 2.0 * math.pi * (1.0 - np.sqrt(1.0 - sin_a ** 2))
        probs = np.maximum(omega_a, 1e-12) / np.maximum(omega_a, 1e-12).sum()
        j = rng.choice(K, size=n, p=probs)
        to_c = centers[j] - o
        dist = np.linalg.norm(to_c, axis=1)
        axis = to_c / np.maximum(dist, 1e-300)[:, None]
        cos_max = np.sqrt(np.maximum(0.0, 1.0 - (radii[j] / np.maximum(dist, 1e-300)) ** 2))
        cos_max = np.where(dist <= radii[j], -1.0, cos_max)  # inside: whole sphere
        d = to_world(uniform_cone(u3, u4, cos_max), axis)
        aimed = np.zeros(n)
        for k in range(K):
            to_k = centers[k] - o
            dk = np.linalg.norm(to_k, axis=1)
            cos_k = np.sqrt(np.maximum(0.0, 1.0 - (radii[k] / np.maximum(dk, 1e-300)) ** 2))
            cos_k = np.where(dk <= radii[k], -1.0, cos_k)
            inside = dot(d, to_k) >= cos_k * dk
            aimed += probs[k] * inside / (2.0 * math.pi * (1.0 - cos_k))
        aimed = np.maximum(aimed, 1e-300)
        if self.kind == MESH:
            cos = np.abs(dot(d, normal))
            scale = self.tri_area[tri] * cos / (self.prob[tri] * n * aimed)
            return (offset_origin(o, normal, d, self._mesh_offset(tri, b1, b2, o)), d,
                    self.tri_L[tri] * scale[:, None])
        if self.kind == AREA:
            cos = dot(d, self.dir)
            pdf_nat = np.maximum(cos, 0.0) / math.pi * spread_attenuation(cos, self.spread)
            return o, d, (self.flux / n)[None, :] * (pdf_nat / aimed)[:, None]
        if self.kind == SPOT:
            mask = self._spot(d)
            if self.radius > 0:
                x, yy = concentric_disk(rng.random(n), rng.random(n))
                t, b = orthonormal_basis(d)
                o = o + self.radius * (x[:, None] * t + yy[:, None] * b)
            return o, d, self.intensity[None, :] * (mask / (n * aimed))[:, None]
        if normal is not None:  # point light with a radius
            pdf_nat = np.maximum(dot(d, normal), 0.0) / math.pi
        else:
            pdf_nat = np.full(n, 1.0 / (4.0 * math.pi))
        return o, d, (self.flux / n)[None, :] * (pdf_nat / aimed)[:, None]

    # ------------------------------------------------------------------ seen in mirrors
    def intersect(self, o, d, tmax):
        """Rays that hit this light's emitting surface before tmax: (mask, t, radiance).
        Only area lights and point/spot lights with a radius have a surface."""
        n = len(o)
        none = (np.zeros(n, bool), np.full(n, np.inf), None)
        if self.kind == AREA:
            denom = dot(d, self.dir)
            facing = denom < -1e-12  # one-sided: the ray must travel against the emission
            t = np.where(facing, dot(self.pos - o, self.dir) / np.where(facing, denom, -1.0), np.inf)
            hitp = o + np.where(np.isfinite(t), t, 0.0)[:, None] * d - self.pos
            x, y = dot(hitp, self.u) / (self.size_x / 2), dot(hitp, self.v) / (self.size_y / 2)
            inside = (x * x + y * y <= 1.0) if self.shape == DISK else ((np.abs(x) <= 1) & (np.abs(y) <= 1))
            mask = facing & inside & (t > 0) & (t < tmax)
            L = np.broadcast_to(self.radiance, (n, 3))
            if self.spread < math.pi:
                L = L * spread_attenuation(-denom, self.spread)[:, None]
            return mask, t, L
        if self.kind in (POINT, SPOT) and self.radius > 0:
            oc = o - self.pos
            b = dot(oc, d)
            c = dot(oc, oc) - self.radius ** 2
            disc = b * b - c
            sq = np.sqrt(np.maximum(disc, 0.0))
            t0 = -b - sq
            t = np.where(t0 > 0, t0, -b + sq)
            mask = (disc > 0) & (t > 0) & (t < tmax) & (c > 0)
            L = np.broadcast_to(self.intensity / (math.pi * self.radius ** 2), (n, 3))
            if self.kind == SPOT:
                L = L * self._spot(-d)[:, None]
            return mask, t, L
        return none

    def seen_at_infinity(self, d):
        """Radiance of a sun disk (angle > 0) seen along escaping directions d."""
        if self.kind != SUN or self.cos_half_angle >= 1.0:
            return None
        inside = dot(d, -self.dir) >= self.cos_half_angle
        return inside[:, None] * self.sun_radiance[None, :]


def _min_dist2(p, y):
    """Squared distance below which 1/d^2 is not evaluated: a light touching the surface
    must not give inf. The floor is what float32 can resolve at the two points (16 ulps of
    their largest coordinates), a local length, never a share of the scene's size."""
    d = 16.0 * (ulp32(max3(np.abs(p))) + ulp32(max3(np.abs(np.broadcast_to(y, p.shape)))))
    return d * d


def prepare_lights(scene: Scene, geo: Geometry, table: MaterialTable) -> list[PreparedLight]:
    """Re-centre the scene's lights and add mesh and world lights."""
    out = []
    center = (geo.bounds[0] + geo.bounds[1]) / 2.0
    radius = max(geo.extent / 2.0, 1e-6) * 1.01
    common = dict(center=center, scene_radius=radius)
    for light in scene.lights:
        rgb = light.power * light.color
        c = float(np.dot(light.axis_u, light.axis_v))
        du = (light.axis_u - c * light.axis_v) / (1.0 - c * c)
        dv = (light.axis_v - c * light.axis_u) / (1.0 - c * c)
        kw = dict(common, pos=light.position - geo.offset, dir=light.direction, u=light.axis_u,
                  v=light.axis_v, du=du, dv=dv, radius=light.radius, spot_size=light.spot_size,
                  spot_blend=light.spot_blend, shape=light.shape, size_x=light.size_x,
                  size_y=light.size_y, spread=light.spread, visible_camera=light.visible_camera,
                  cos_half_angle=1.0, source=light)
        if light.kind == SPOT:
            frame = light.cone_frame
            kw.update(spot_frame=frame,
                      spot_cos_bound=spot_bounding_cos(light.spot_size, frame, light.direction))
        if light.kind in (POINT, SPOT):
            intensity = rgb / (4.0 * math.pi)
            kw.update(intensity=intensity, flux=light.flux, photon_flux=light.flux)
        elif light.kind == AREA:
            if light.area <= 0:
                continue
            flux = light.flux
            kw.update(area=light.area, flux=flux, radiance=flux / (math.pi * light.area),
                      photon_flux=flux)
        elif light.kind == SUN:
            half = light.angle / 2.0
            cos_half = math.cos(half)
            solid = 2.0 * math.pi * (1.0 - cos_half)
            kw.update(irradiance=rgb, cos_half_angle=cos_half,
                      sun_radiance=rgb / max(math.pi * math.sin(half) ** 2, 1e-300) if half > 0 else rgb,
                      photon_flux=rgb * math.pi * radius ** 2, solid_angle=solid)
        out.append(PreparedLight(light.name, light.kind, **kw))

    idx, L, area = emissive_triangles(geo, table)
    if len(idx):
        weight = area * luminance(L)
        if weight.sum() <= 0:
            weight = area.copy()
        prob = weight / weight.sum()
        cdf = np.cumsum(prob)
        cdf[-1] = 1.0
        flux = (2.0 * math.pi * area[:, None] * L).sum(axis=0)
        out.append(PreparedLight(
            "emissive meshes", MESH, v0=geo.v0[idx], e1=geo.e1[idx], e2=geo.e2[idx],
            tri_ng=geo.ng[idx], tri_L=L, tri_area=area, prob=prob, cdf=cdf,
            tri_index=idx, photon_flux=flux, flux=flux, radius=0.0, visible_camera=True,
            round32=geo.round32[idx], tilt32=geo.tilt32[idx],
            cos_half_angle=1.0, **common))
    bg = np.asarray(scene.background, np.float64)
    if scene.background_is_light and np.any(bg > 0):
        out.append(PreparedLight(
            "world", WORLD, radiance=bg, photon_flux=bg * math.pi * radius ** 2 * 4.0 * math.pi,
            radius=0.0, visible_camera=True, cos_half_angle=1.0, **common))
    return out


def allocate_photons(lights: list[PreparedLight], total: int) -> list[int]:
    """Photons per light, proportional to emitted power (the paper: power-proportional)."""
    w = np.array([float(luminance(np.asarray(li.photon_flux))) for li in lights])
    if total <= 0 or len(w) == 0 or w.sum() <= 0:
        return [0] * len(lights)
    share = w / w.sum() * total
    counts = np.floor(share).astype(int)
    rest = total - counts.sum()
    order = np.argsort(-(share - counts))
    counts[order[:rest]] += 1
    return counts.tolist()

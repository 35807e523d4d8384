"""Panoramic cameras as Cycles makes them (intern/cycles/kernel/camera/projection.h,
camera.h camera_sample_panorama; blender/camera.cpp for the frame and the sensor).

A panoramic camera maps the image to directions, not to a plane: (u, v) in [0, 1]^2
across the image (u = shift_x + x / width from the left, v = shift_y + y / height from
the bottom) gives a direction in the panorama's own frame, where +x is the view
direction, +z up (for the fisheye kinds: x forward, y left, z up); the frame turns into
Blender's camera object axes by Cycles' fixed matrix (FRAME; the mirror ball its own,
looking along its -y). A direction of length 0 means "outside the lens": the pixel gets
no light (a fisheye's circle).

Kinds (Blender's Camera > Panorama Type):
  EQUIRECTANGULAR           phi = (lon_min - lon_max) u - lon_min, theta = (lat_min -
                            lat_max) v - lat_min + pi/2; (sin t cos p, sin t sin p, cos t)
  EQUIANGULAR_CUBEMAP_FACE  normalize(1, tan((0.5 - u) pi/2), tan((v - 0.5) pi/2))
  MIRRORBALL                the reflection of (0, -1, 0) off a unit ball seen from +y
  FISHEYE_EQUIDISTANT       theta = r fov / 2, r the distance from the centre over the
                            half image (r > 1: outside)
  FISHEYE_EQUISOLID         theta = 2 asin(r / 2 lens), r in mm on the fitted sensor,
                            outside past 2 lens sin(fov / 4)
  FISHEYE_LENS_POLYNOMIAL   theta = -(k0 + k1 r + k2 r^2 + k3 r^3 + k4 r^4), r in mm,
                            outside where |theta| > fov / 2
  CENTRAL_CYLINDRICAL       (cos t, sin t, h), t from -u_min to -u_max, h from v_min to
                            v_max over the radius
Depth of field as Cycles: the lens in the plane across the pixel's direction.
"""
from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from .jit import kernel

KINDS = ("EQUIRECTANGULAR", "EQUIANGULAR_CUBEMAP_FACE", "MIRRORBALL", "FISHEYE_EQUIDISTANT",
         "FISHEYE_EQUISOLID", "FISHEYE_LENS_POLYNOMIAL", "CENTRAL_CYLINDRICAL")
EQUIRECTANGULAR, CUBEMAP_FACE, MIRRORBALL, EQUIDISTANT, EQUISOLID, POLYNOMIAL, CYLINDRICAL = \
    range(len(KINDS))

# Cycles' blender_camera_matrix: the panorama's frame in Blender's camera object axes
# (rows: object x, y, z), so the camera looks along its -z at the map's centre.
FRAME = np.array([[0.0, -1.0, 0.0], [0.0, 0.0, 1.0], [-1.0, 0.0, 0.0]])
FRAME_MIRRORBALL = np.array([[1.0, 0.0, 0.0], [0.0, 0.0, 1.0], [0.0, 1.0, 0.0]])

# The packed parameters (pack): a float64 row the camera-ray kernel reads.
P_KIND, P_RANGE, P_FOV, P_LENS, P_SENSOR_W, P_SENSOR_H, P_K, P_CYL, P_FRAME = (
    0, 1, 5, 6, 7, 8, 9, 14, 18)
P_SIZE = 27


@dataclass
class Panorama:
    """Blender's panoramic camera settings (Camera data): `kind` one of KINDS; angles in
    radians, fisheye_lens and sensor sizes in mm; fisheye_polynomial (k0..k4);
    cylindrical_range (u_min, u_max, v_min, v_max) and cylindrical_radius."""

    kind: str = "EQUIRECTANGULAR"
    fisheye_fov: float = math.pi
    fisheye_lens: float = 10.5
    sensor_width: float = 36.0
    sensor_height: float = 24.0
    latitude_min: float = -0.5 * math.pi
    latitude_max: float = 0.5 * math.pi
    longitude_min: float = -math.pi
    longitude_max: float = math.pi
    fisheye_polynomial: tuple = (-1.1735143e-05, -0.019988736, -3.3525322e-06,
                                 3.0994751e-06, -2.6198899e-08)
    cylindrical_range: tuple = (-math.pi, math.pi, -1.0, 1.0)
    cylindrical_radius: float = 1.0

    def __post_init__(self):
        self.kind = str(self.kind).upper()
        if self.kind not in KINDS:
            raise ValueError(f"panorama kind {self.kind!r}: expected one of {KINDS}")
        vals = [self.fisheye_fov, self.fisheye_lens, self.sensor_width, self.sensor_height,
                self.latitude_min, self.latitude_max, self.longitude_min, self.longitude_max,
                self.cylindrical_radius, *self.fisheye_polynomial, *self.cylindrical_range]
        if not np.all(np.isfinite(np.asarray(vals, np.float64))):
            raise ValueError(f"panorama settings must be finite, got {vals}")
        if len(self.fisheye_polynomial) != 5 or len(self.cylindrical_range) != 4:
            raise ValueError("panorama: fisheye_polynomial takes 5 numbers (k0..k4), "
                             "cylindrical_range 4 (u_min, u_max, v_min, v_max)")
        if min(self.fisheye_lens, self.sensor_width, self.sensor_height,
               self.cylindrical_radius) <= 0.0 or self.fisheye_fov <= 0.0:
            raise ValueError("panorama: fisheye lens, fov, sensor sizes and cylinder radius "
                             "must be > 0")

    def fitted_sensor(self, width: int, height: int, sensor_fit: str) -> tuple:
        """(width, height) in mm of the sensor the fisheye kinds map the image onto:
        Cycles' blender_camera_sync (the sensor size by fit, the other side by the
        image's aspect)."""
        horizontal = width > height if sensor_fit == "AUTO" else sensor_fit == "HORIZONTAL"
        size = self.sensor_height if sensor_fit == "VERTICAL" else self.sensor_width
        if horizontal:
            return size, size * height / width
        return size * width / height, size

    def pack(self, width: int, height: int, sensor_fit: str) -> np.ndarray:
        """(P_SIZE,) float64: the kernel's parameters (module constants P_*)."""
        p = np.zeros(P_SIZE)
        p[P_KIND] = KINDS.index(self.kind)
        p[P_RANGE:P_RANGE + 4] = (self.longitude_min - self.longitude_max, -self.longitude_min,
                                  self.latitude_min - self.latitude_max,
                                  -self.latitude_min + 0.5 * math.pi)
        p[P_FOV], p[P_LENS] = self.fisheye_fov, self.fisheye_lens
        p[P_SENSOR_W], p[P_SENSOR_H] = self.fitted_sensor(width, height, sensor_fit)
        p[P_K:P_K + 5] = self.fisheye_polynomial
        u0, u1, v0, v1 = self.cylindrical_range
        r = self.cylindrical_radius
        p[P_CYL:P_CYL + 4] = (-u0, -u1, v0 / r, v1 / r)
        p[P_FRAME:P_FRAME + 9] = self.frame.ravel()
        return p

    @property
    def frame(self) -> np.ndarray:
        """(3,3) this kind's frame in the camera object's axes (FRAME, FRAME_MIRRORBALL)."""
        return FRAME_MIRRORBALL if self.kind == "MIRRORBALL" else FRAME

    def pixel_angle(self, width: int, height: int) -> float:
        """A pixel's angular size (rad) across the image's larger side, roughly: what a
        pinhole's 2 tan(fov / 2) / width is to the ray footprint."""
        k = self.kind
        if k == "EQUIRECTANGULAR":
            span = max(abs(self.longitude_max - self.longitude_min) / max(width, 1),
                       abs(self.latitude_max - self.latitude_min) / max(height, 1))
            return span
        if k == "CENTRAL_CYLINDRICAL":
            return abs(self.cylindrical_range[1] - self.cylindrical_range[0]) / max(width, 1)
        if k == "EQUIANGULAR_CUBEMAP_FACE":
            return 0.5 * math.pi / max(width, height, 1)
        if k == "MIRRORBALL":
            return 2.0 * math.pi / max(width, height, 1)
        return self.fisheye_fov / max(width, height, 1)


@kernel
def _fisheye(theta, u, v, r):
    """Cycles' fisheye_to_direction: x along the axis, y and z across it."""
    c = u / r if r != 0.0 else 0.0
    phi = math.acos(min(max(c, -1.0), 1.0))
    if v < 0.0:
        phi = -phi
    return math.cos(theta), -math.cos(phi) * math.sin(theta), math.sin(phi) * math.sin(theta)


@kernel
def panorama_direction(p, u, v):
    """The direction (x, y, z) in the panorama's frame for image coordinates u, v in [0, 1]
    (from the left and the bottom), not normalised; (0, 0, 0) outside the lens. p: the
    packed parameters (Panorama.pack)."""
    kind = int(p[P_KIND])
    if kind == EQUIRECTANGULAR:
        phi = p[P_RANGE] * u + p[P_RANGE + 1]
        theta = p[P_RANGE + 2] * v + p[P_RANGE + 3]
        s = math.sin(theta)
        return s * math.cos(phi), s * math.sin(phi), math.cos(theta)
    if kind == CUBEMAP_FACE:
        a = math.tan((0.5 - u) * 0.5 * math.pi)
        b = math.tan((v - 0.5) * 0.5 * math.pi)
        n = math.sqrt(1.0 + a * a + b * b)
        return 1.0 / n, a / n, b / n
    if kind == MIRRORBALL:
        x = 2.0 * u - 1.0
        z = 2.0 * v - 1.0
        if x * x + z * z > 1.0:
            return 0.0, 0.0, 0.0
        y = -math.sqrt(max(1.0 - x * x - z * z, 0.0))
        # the reflection of I = (0, -1, 0): 2 (n . I) n - I
        k = 2.0 * (-y)
        return k * x, k * y + 1.0, k * z
    if kind == CYLINDRICAL:
        theta = p[P_CYL] + (p[P_CYL + 1] - p[P_CYL]) * u
        h = p[P_CYL + 2] + (p[P_CYL + 3] - p[P_CYL + 2]) * v
        return math.cos(theta), math.sin(theta), h
    if kind == EQUIDISTANT:
        a = (u - 0.5) * 2.0
        b = (v - 0.5) * 2.0
        r = math.sqrt(a * a + b * b)
        if r > 1.0:
            return 0.0, 0.0, 0.0
        return _fisheye(r * p[P_FOV] * 0.5, a, b, r)
    a = (u - 0.5) * p[P_SENSOR_W]
    b = (v - 0.5) * p[P_SENSOR_H]
    r = math.sqrt(a * a + b * b)
    if kind == POLYNOMIAL:
        r2 = r * r
        theta = -(p[P_K] + p[P_K + 1] * r + p[P_K + 2] * r2 + p[P_K + 3] * r2 * r
                  + p[P_K + 4] * r2 * r2)
        if abs(theta) > 0.5 * p[P_FOV]:
            return 0.0, 0.0, 0.0
        return _fisheye(theta, a, b, r)
    lens = p[P_LENS]
    if r > 2.0 * lens * math.sin(p[P_FOV] * 0.25):
        return 0.0, 0.0, 0.0
    return _fisheye(2.0 * math.asin(min(r / (2.0 * lens), 1.0)), a, b, r)


def frame(p: np.ndarray) -> np.ndarray:
    """(3,3) the packed panorama's frame in the camera object's axes (rows x, y, z)."""
    return np.asarray(p[P_FRAME:P_FRAME + 9], np.float64).reshape(3, 3)


def directions_to_uv(p: np.ndarray, d: np.ndarray) -> np.ndarray:
    """(N,2) image coordinates u, v (from the left and the bottom) of directions d (N,3)
    in the panorama's frame (Cycles' direction_to_panorama); NaN where none maps there."""
    d = np.asarray(d, np.float64)
    x, y, z = d[:, 0], d[:, 1], d[:, 2]
    kind = int(p[P_KIND])
    with np.errstate(invalid="ignore", divide="ignore"):
        length = np.sqrt(x * x + y * y + z * z)
        if kind == EQUIRECTANGULAR:
            u = (np.arctan2(y, x) - p[P_RANGE + 1]) / p[P_RANGE]
            v = (np.arccos(np.clip(z / length, -1.0, 1.0)) - p[P_RANGE + 3]) / p[P_RANGE + 2]
            return np.stack([u, v], axis=1)
        if kind == CUBEMAP_FACE:
            u = 0.5 - np.arctan2(y, x) * 2.0 / math.pi
            v = np.arctan2(z, x) * 2.0 / math.pi + 0.5
            return np.where((x > 0)[:, None], np.stack([u, v], axis=1), np.nan)
        if kind == MIRRORBALL:
            n = d / length[:, None]
            ny = n[:, 1] - 1.0
            div = 2.0 * np.sqrt(np.maximum(-0.5 * ny, 0.0))
            div = np.where(div > 0.0, div, 1.0)
            return np.stack([0.5 * (n[:, 0] / div + 1.0), 0.5 * (n[:, 2] / div + 1.0)], axis=1)
        if kind == CYLINDRICAL:
            h = z / np.hypot(x, y)
            theta = np.arctan2(y, x)
            c = p[P_CYL:P_CYL + 4]
            return np.stack([(theta - c[0]) / (c[1] - c[0]), (h - c[2]) / (c[3] - c[2])],
                            axis=1)
        across = np.hypot(y, z)
        side = np.stack([y, z], axis=1) / np.where(across > 0, across, 1.0)[:, None]
        if kind == EQUIDISTANT:
            r = np.arctan2(across, x) / p[P_FOV]
            uv = r[:, None] * side
            out = np.stack([0.5 - uv[:, 0], uv[:, 1] + 0.5], axis=1)
            return np.where((r <= 0.5)[:, None], out, np.nan)
        theta = np.arccos(np.clip(x / length, -1.0, 1.0))
        w, hgt = p[P_SENSOR_W], p[P_SENSOR_H]
        if kind == POLYNOMIAL:
            k = p[P_K:P_K + 5]
            t = -theta
            r = (t - k[0]) / k[1] if k[1] != 0 else np.zeros_like(t)
            for _ in range(20):  # Newton, as Cycles' direction_to_fisheye_lens_polynomial
                r2 = r * r
                f = t - (k[0] + k[1] * r + k[2] * r2 + k[3] * r2 * r + k[4] * r2 * r2)
                df = k[1] + 2 * k[2] * r + 3 * k[3] * r2 + 4 * k[4] * r2 * r
                r = r + f / df
            inside = theta <= 0.5 * p[P_FOV]
        else:
            r = 2.0 * p[P_LENS] * np.sin(theta * 0.5)
            inside = theta <= 0.5 * p[P_FOV]
        uv = r[:, None] * side
        out = np.stack([0.5 - uv[:, 0] / w, uv[:, 1] / hgt + 0.5], axis=1)
        return np.where(inside[:, None], out, np.nan)

"""Blender's Sky Texture (a world's Background colour) as the engine lights it: the sky
baked into an equirectangular Environment (engine/lights/environment.py, importance
sampled for shadow rays and photons) and the sun disc as a separate sun light.

Two of Blender's models, reimplemented in numpy from Blender's intern/sky/source/ and
Cycles' scene/shader_nodes.cpp SkyTextureNode and kernel/svm/sky.h (checked against Cycles
5.0.1 through the bpy wheel: tests/test_sky.py): Single Scattering (Blender 4.2-4.5's
"Nishita", described below) and Multiple Scattering (5.0's default: four wavelengths, a
transmittance table, a fitted multiple-scattering term and light from a grey ground; the
table covers both hemispheres, the sun disc sets at the Earth's limb; see its section).
Preetham and Hosek / Wilkie (analytic fits, no disc; Hosek / Wilkie's coefficients in
sky_hosek_data.py, (c) Lukas Hosek and Alexander Wilkie, BSD-3-Clause) are evaluated at
each texel.

  sky       single scattering of sunlight by air (Rayleigh) and aerosols (Mie, g = 0.76)
            along the view ray through a spherical atmosphere (Earth radius 6360 km,
            atmosphere 6420 km, scale heights 8 km and 1.2 km, an ozone layer 10-40 km
            that only absorbs), at 21 wavelengths 380-780 nm, 32 midpoint steps along the
            view ray and an 8-node Gauss-Laguerre quadrature for the optical depth
            towards the sun; the spectrum -> CIE XYZ -> linear Rec.709 (clamped >= 0).
            As Cycles, the sky is first tabulated in a 512 x 256 table (upper half:
            elevation = pi/2 t^2 per row, dense at the horizon; longitude relative to the
            sun, mirrored; lower half: the horizon's colour faded by (1 - 2.5 |z|)^3,
            black from |z| = 0.4) and looked up bilinearly.
  sun disc  radiance = sun irradiance x transmittance along the sun's direction / the
            disc's solid angle, interpolated between the disc's bottom and top edge and
            limb darkened by 1 - 0.6 (1 - sqrt(1 - (a / a_half)^2)); seen down to the
            Earth's limb (0.32 degrees below the horizon at 100 m); an edge below the
            horizon takes the horizon's value, a disc wholly below it is black. Here it is a sun light (engine/lights/sun.py) of angle sun_size and
            the disc's irradiance (its radiance integrated over the disc: limb darkening
            averages to 0.8), so it is sampled as a light, as Cycles samples the sky's
            sun separately, instead of a few texels of the map.

Conventions (Cycles'): sun_rotation 0 puts the sun towards +Y, increasing clockwise seen
from above (towards +X); the sky seen along world direction d is the sky at
rotation @ d (the Mapping node in front of the texture), as the Environment's.

Units: radiance per unit Background strength (W / (m^2 sr) in Cycles' convention), the
sun light's irradiance in W / m^2.
"""
from __future__ import annotations

import functools
import math
from dataclasses import dataclass, field

import numpy as np

SKY_TYPES = ("SINGLE_SCATTERING", "MULTIPLE_SCATTERING", "PREETHAM", "HOSEK_WILKIE")
# The types baked here; the others are warned about by the caller.
SUPPORTED_SKY_TYPES = ("SINGLE_SCATTERING", "MULTIPLE_SCATTERING", "PREETHAM", "HOSEK_WILKIE")
# The analytic fits: a sun from the node's sun_direction, turbidity, no disc.
ANALYTIC_SKY_TYPES = ("PREETHAM", "HOSEK_WILKIE")
# Blender 4.x spelling of the Single Scattering model.
SKY_TYPE_ALIASES = {"NISHITA": "SINGLE_SCATTERING"}

# Baked map: 1024 x 512 texels (0.35 degrees): twice the table's azimuth resolution
# (512 columns over 360 degrees) and finer in elevation than the table above ~5 degrees,
# so the map adds no visible error to Cycles' own bilinear table; 6 MB as float32.
BAKE_WIDTH, BAKE_HEIGHT = 1024, 512
TABLE_WIDTH, TABLE_HEIGHT = 512, 256

# --- the atmosphere (Blender's intern/sky tables: 21 wavelengths, 380..780 nm) ----------
RAYLEIGH_SCALE = 8e3       # m
MIE_SCALE = 1.2e3          # m
MIE_COEFF = 2e-5           # 1/m
MIE_G = 0.76
EARTH_RADIUS = 6360e3      # m
ATMOSPHERE_RADIUS = 6420e3  # m
STEPS = 32
STEP_LAMBDA = 20.0         # nm
# Sun spectral irradiance at the top of the atmosphere (W m^-2 nm^-1).
SUN_IRRADIANCE = np.array([
    1.45756829855592995315, 1.56596305559738380175, 1.65148449067670455293,
    1.71496242737209314555, 1.75797983805020541226, 1.78256407885924539336,
    1.79095108475838560302, 1.78541550133410664714, 1.76815554864306845317,
    1.74122069647250410362, 1.70647127164943679389, 1.66556087452739887134,
    1.61993437242451854274, 1.57083597368892080581, 1.51932335059305478886,
    1.46628494965214395407, 1.41245852740172450623, 1.35844961970384092709,
    1.30474913844739281998, 1.25174963272610817455, 1.19975998755420620867])
RAYLEIGH_COEFF = np.array([
    5.424820087636473e-05, 4.418549866505454e-05, 3.635151910165377e-05,
    3.017929012024763e-05, 2.526320226989157e-05, 2.130859310621843e-05,
    1.809838025320633e-05, 1.547057129129042e-05, 1.330284977336850e-05,
    1.150184784075764e-05, 9.99557429990163e-06, 8.72799973630707e-06,
    7.65513700977967e-06, 6.74217203751443e-06, 5.96134125832052e-06,
    5.29034598065810e-06, 4.71115687557433e-06, 4.20910481110487e-06,
    3.77218381260133e-06, 3.39051255477280e-06, 3.05591531679811e-06])
OZONE_COEFF = np.array([
    3.25126849861e-09, 5.85395365047e-09, 1.977191155085e-08, 7.309568762914e-08,
    2.0084561514287e-07, 4.0383958096161e-07, 6.3551335912363e-07, 9.6707041180970e-07,
    1.54797400424410e-06, 2.09038647223331e-06, 2.46128056164565e-06,
    2.73551299461512e-06, 2.15125863128643e-06, 1.59051840791988e-06,
    1.12356197979857e-06, 7.3527551487574e-07, 4.6450130357806e-07, 3.3096079921048e-07,
    2.2512612292678e-07, 1.4879129266490e-07, 1.6828623364192e-07])
# CIE 1931 colour matching functions at the same wavelengths (x, y, z).
CMF_XYZ = np.array([
    [0.00136800000, 0.00003900000, 0.00645000100], [0.01431000000, 0.00039600000, 0.06785001000],
    [0.13438000000, 0.00400000000, 0.64560000000], [0.34828000000, 0.02300000000, 1.74706000000],
    [0.29080000000, 0.06000000000, 1.66920000000], [0.09564000000, 0.13902000000, 0.81295010000],
    [0.00490000000, 0.32300000000, 0.27200000000], [0.06327000000, 0.71000000000, 0.07824999000],
    [0.29040000000, 0.95400000000, 0.02030000000], [0.59450000000, 0.99500000000, 0.00390000000],
    [0.91630000000, 0.87000000000, 0.00165000100], [1.06220000000, 0.63100000000, 0.00080000000],
    [0.85444990000, 0.38100000000, 0.00019000000], [0.44790000000, 0.17500000000, 0.00002000000],
    [0.16490000000, 0.06100000000, 0.00000000000], [0.04677000000, 0.01700000000, 0.00000000000],
    [0.01135916000, 0.00410200000, 0.00000000000], [0.00289932700, 0.00104700000, 0.00000000000],
    [0.00069007860, 0.00024920000, 0.00000000000], [0.00016615050, 0.00006000000, 0.00000000000],
    [0.00004150994, 0.00001499000, 0.00000000000]])
# Gauss-Laguerre nodes (n = 8, scaled so the last node stays inside the atmosphere: x/25)
# and weights w exp(x) / 25: the optical depth integral of a density that falls roughly
# exponentially along the ray.
QUADRATURE_NODES = np.array([0.006811185292, 0.03614807107, 0.09004346519, 0.1706680068,
                             0.2818362161, 0.4303406404, 0.6296271457, 0.9145252695])
QUADRATURE_WEIGHTS = np.array([0.01750893642, 0.04135477391, 0.06678839063, 0.09507698807,
                               0.1283416365, 0.1707430204, 0.2327233347, 0.3562490486])
# CIE XYZ -> linear Rec.709 (the D65 sRGB matrix): Cycles' xyz_to_rgb under Blender 5.0's
# default configuration (scene linear = Rec.709) reproduced its sky to 0.1 % per channel.
XYZ_TO_REC709 = np.array([[3.2404542, -1.5371385, -0.4985314],
                          [-0.9692660, 1.8760108, 0.0415560],
                          [0.0556434, -0.2040259, 1.0572252]])
LIMB_DARKENING = 0.6
MIN_SUN_SIZE = 0.0005  # Cycles clamps the disc's angular diameter (numerical issues)


def xyz_to_rec709(xyz: np.ndarray) -> np.ndarray:
    """(..., 3) CIE XYZ -> linear Rec.709, negative components clamped to 0 (Cycles'
    xyz_to_rgb_clamped)."""
    return np.maximum(np.asarray(xyz) @ XYZ_TO_REC709.T, 0.0)


# --- the model --------------------------------------------------------------------------

def _densities(height: np.ndarray) -> np.ndarray:
    """(..., 3) relative densities of air, aerosols and ozone at heights (m) above sea
    level: exponentials of scale height 8 km and 1.2 km; ozone a tent 10-40 km peaking
    at 25 km."""
    return np.stack([np.exp(-height / RAYLEIGH_SCALE), np.exp(-height / MIE_SCALE),
                     np.maximum(0.0, 1.0 - np.abs(height - 25000.0) / 15000.0)], axis=-1)


def _phases(mu: np.ndarray) -> np.ndarray:
    """(..., 2) Rayleigh and Mie (Cornette-Shanks, g = 0.76) phase functions (1/sr) at
    the cosine mu between the view ray and the sun."""
    g2 = MIE_G * MIE_G
    rayleigh = 3.0 / (16.0 * math.pi) * (1.0 + mu * mu)
    mie = (3.0 * (1.0 - g2) * (1.0 + mu * mu)) / (
        8.0 * math.pi * (2.0 + g2) * (1.0 + g2 - 2.0 * MIE_G * mu) ** 1.5)
    return np.stack([rayleigh, mie], axis=-1)


def _exit_length(r2: np.ndarray, b: np.ndarray) -> np.ndarray:
    """Distance (m) along a unit direction to the atmosphere's outer sphere from a point
    at squared distance r2 from the Earth's centre, b = the point . the direction."""
    return -b + np.sqrt(np.maximum(b * b - (r2 - ATMOSPHERE_RADIUS ** 2), 0.0))


def _column(r2: np.ndarray, b: np.ndarray) -> np.ndarray:
    """(..., 3) column densities (m, per unit relative density) of air, aerosols and
    ozone from a point (squared distance r2 from the centre) along a unit direction (b =
    point . direction) out of the atmosphere: Gauss-Laguerre nodes along the path; a
    node at distance t is at radius sqrt(r2 + 2 t b + t^2)."""
    length = _exit_length(r2, b)
    total = 0.0
    for x, w in zip(QUADRATURE_NODES, QUADRATURE_WEIGHTS):
        t = x * length
        total = total + w * _densities(np.sqrt(r2 + t * (2.0 * b + t)) - EARTH_RADIUS)
    return total * length[..., None]


def optical_depth(pos: np.ndarray, d: np.ndarray) -> np.ndarray:
    """(..., 3) column densities (m, per unit relative density) of air, aerosols and
    ozone from pos (..., 3) along unit d (..., 3) out of the atmosphere."""
    pos = np.asarray(pos, np.float64)
    return _column(np.einsum("...i,...i->...", pos, pos), np.einsum("...i,...i->...", pos, d))


def sun_direction_local(elevation: float) -> np.ndarray:
    """Unit direction to the sun in the model's frame (sun at longitude 0: +X)."""
    return np.array([math.cos(elevation), 0.0, math.sin(elevation)])


def single_scattering_spectrum(dirs: np.ndarray, sun_elevation: float, altitude: float,
                               air: float = 1.0, aerosol: float = 1.0,
                               ozone: float = 1.0) -> np.ndarray:
    """(N, 21) spectral radiance (W m^-2 sr^-1 nm^-1) of the sky along unit directions
    dirs (N, 3) (model frame: +Z up, the sun at longitude 0) seen from `altitude` m above
    sea level; sunlight scattered once at the midpoints of 32 equal steps to the
    atmosphere's edge, attenuated on its way in and out (Earth's shadow: none where the
    sun is hidden)."""
    dirs = np.asarray(dirs, np.float64).reshape(-1, 3)
    sun = sun_direction_local(sun_elevation)
    r0 = EARTH_RADIUS + altitude
    # The camera sits at (0, 0, r0): a point s along d is at squared radius
    # r0^2 + 2 s r0 d_z + s^2 and has point . sun = r0 sun_z + s (d . sun).
    dz = dirs[:, 2]
    mu = dirs @ sun
    seg = _exit_length(np.full(len(dirs), r0 * r0), r0 * dz) / STEPS
    scale = np.array([air, aerosol, ozone])
    # extinction per unit column (air, aerosol, ozone) x wavelength: aerosols also absorb
    # (extinction 1.11 x scattering)
    ext = np.stack([RAYLEIGH_COEFF, np.full(21, 1.11 * MIE_COEFF), OZONE_COEFF])
    phase = _phases(mu)  # (N, 2)
    spectrum = np.zeros((len(dirs), 21))
    depth = np.zeros((len(dirs), 3))
    for i in range(STEPS):
        s = (i + 0.5) * seg
        r2 = r0 * r0 + s * (2.0 * r0 * dz + s)
        dens = scale * _densities(np.sqrt(r2) - EARTH_RADIUS)
        depth += seg[:, None] * dens
        b = r0 * sun[2] + s * mu
        # Blender's test: the sun ray heads down and its line meets the Earth's sphere.
        lit = ~((sun[2] < 0) & (b * b - (r2 - EARTH_RADIUS ** 2) >= 0))
        if not lit.any():
            continue
        total = depth + scale * _column(r2, b)
        # in place: (N, 21) temporaries dominate the cost
        attenuation = total @ ext
        np.negative(attenuation, out=attenuation)
        np.exp(attenuation, out=attenuation)
        w = lit * seg
        term = np.multiply.outer(w * phase[:, 0] * dens[:, 0], RAYLEIGH_COEFF)
        term += (w * phase[:, 1] * dens[:, 1] * MIE_COEFF)[:, None]
        term *= attenuation
        spectrum += term
    return spectrum * SUN_IRRADIANCE


def spectrum_to_xyz(spectrum: np.ndarray) -> np.ndarray:
    """(..., 21) spectral radiance -> (..., 3) CIE XYZ (Riemann sum, 20 nm steps)."""
    return (spectrum @ CMF_XYZ) * STEP_LAMBDA


def sky_table(sun_elevation: float, altitude: float, air: float = 1.0,
              aerosol: float = 1.0, ozone: float = 1.0, width: int = TABLE_WIDTH,
              height: int = TABLE_HEIGHT) -> np.ndarray:
    """(height, width, 3) XYZ table of the sky as Cycles tabulates it: row y >= height/2 at
    elevation pi/2 (2y/height - 1)^2 (dense at the horizon), column x at longitude
    2 pi x / width - pi relative to the sun, mirrored about the sun's side; row y <
    height/2 the horizon row faded by (1 - 2.5 sin(lat))^3 with lat = pi/2 (2y/height -
    1)^2 (black from sin(lat) = 0.4): the ground below the horizon."""
    altitude = min(max(altitude, 1.0), 59999.0)
    half_w, half_h = width // 2, height // 2
    ys = np.arange(half_h, height)
    lat = 0.5 * math.pi * (ys / half_h - 1.0) ** 2
    lon = 2.0 * math.pi / width * np.arange(half_w) - math.pi
    la, lo = np.meshgrid(lat, lon, indexing="ij")
    dirs = np.stack([np.cos(la) * np.cos(lo), np.cos(la) * np.sin(lo), np.sin(la)], axis=-1)
    xyz = spectrum_to_xyz(single_scattering_spectrum(dirs.reshape(-1, 3), sun_elevation,
                                                     altitude, air, aerosol, ozone))
    table = np.zeros((height, width, 3))
    half = xyz.reshape(len(ys), half_w, 3)
    table[ys, :half_w] = half
    table[ys[:, None], (width - 1 - np.arange(half_w))[None, :]] = half
    low = np.arange(half_h)
    z = np.sin(0.5 * math.pi * (low / half_h - 1.0) ** 2)
    fade = np.where(z < 0.4, (1.0 - 2.5 * z) ** 3, 0.0)
    table[low] = table[half_h][None] * fade[:, None, None]
    return table


def _table_lookup(table: np.ndarray, x: np.ndarray, y: np.ndarray) -> np.ndarray:
    """Bilinear lookup of table (H, W, 3) at image coordinates x, y in [0, 1] (texel
    centres at (i + 0.5) / size, clamped at the edges: Cycles' Linear / Extend)."""
    H, W = table.shape[:2]
    fx = np.clip(x * W - 0.5, 0.0, W - 1.0)
    fy = np.clip(y * H - 0.5, 0.0, H - 1.0)
    x0 = np.minimum(fx.astype(np.int64), W - 1)
    y0 = np.minimum(fy.astype(np.int64), H - 1)
    x1 = np.minimum(x0 + 1, W - 1)
    y1 = np.minimum(y0 + 1, H - 1)
    tx = (fx - x0)[:, None]
    ty = (fy - y0)[:, None]
    flat = table.reshape(-1, 3)
    top = flat.take(y0 * W + x0, axis=0) * (1.0 - tx) + flat.take(y0 * W + x1, axis=0) * tx
    low = flat.take(y1 * W + x0, axis=0) * (1.0 - tx) + flat.take(y1 * W + x1, axis=0) * tx
    return top * (1.0 - ty) + low * ty


def sun_edges_xyz(sun_elevation: float, sun_size: float, altitude: float, air: float = 1.0,
                  aerosol: float = 1.0):
    """XYZ radiance of the sun disc at its bottom and top edge: the top-of-atmosphere
    irradiance / the disc's solid angle, attenuated by air and aerosols (not ozone, as
    Blender's) along the edge's direction (clamped at the horizon); black when the whole
    disc is below the horizon."""
    altitude = min(max(altitude, 1.0), 59999.0)
    half = sun_size / 2.0
    solid = 2.0 * math.pi * (1.0 - math.cos(half))
    top = sun_elevation + half
    if not top > 0:
        return np.zeros(3), np.zeros(3)
    out = []
    origin = np.array([[0.0, 0.0, EARTH_RADIUS + altitude]])
    for e in (max(sun_elevation - half, 0.0), top):
        depth = optical_depth(origin, sun_direction_local(e)[None])[0]
        tau = RAYLEIGH_COEFF * depth[0] * air + 1.11 * MIE_COEFF * depth[1] * aerosol
        out.append(spectrum_to_xyz(SUN_IRRADIANCE * np.exp(-tau) / solid))
    return out[0], out[1]


# --- Multiple Scattering (Blender 5.0's default; intern/sky/source/
# sky_multiple_scattering.cpp: Fernando Garcia Linan's spectral sky, MIT licence) ------
# Four wavelengths (630, 560, 490, 430 nm), heights in km, single scattering marched in
# 64 steps with Hillaire's energy-conserving step integral plus a fitted multiple
# scattering term and second-order light from a ground of albedo 0.3.
MS_EARTH_RADIUS = 6371.0      # km
MS_ATMOSPHERE_RADIUS = 6471.0  # km (100 km thick)
MS_THICKNESS = 100.0
MS_STEPS = 64
MS_LUT_X, MS_LUT_Y = 256, 64  # transmittance table: cos(sun zenith) x altitude
MS_G = 0.8
MS_GROUND_ALBEDO = 0.3
MS_SUN_IRRADIANCE = np.array([1.679, 1.828, 1.986, 1.307])
MS_MOLECULAR_SCATTERING = np.array([6.605e-3, 1.067e-2, 1.842e-2, 3.156e-2])
MS_OZONE_CROSS_SECTION = np.array([3.472e-25, 3.914e-25, 1.349e-25, 11.03e-27])
MS_OZONE_DOBSON = 334.5
MS_AEROSOL_ABSORPTION = np.array([2.8722e-24, 4.6168e-24, 7.9706e-24, 1.3578e-23])
MS_AEROSOL_SCATTERING = np.array([1.5908e-22, 1.7711e-22, 2.0942e-22, 2.4033e-22])
MS_AEROSOL_BASE_DENSITY = 1.3681e20
MS_AEROSOL_BACKGROUND_DENSITY = 2e6
MS_AEROSOL_HEIGHT_SCALE = 0.73
# rows: the four wavelengths' contributions to X, Y, Z
MS_SPECTRAL_XYZ = np.array([
    [53.386917738564668023, 22.981337506691024754, 0.0],
    [43.904844466369358263, 71.347795700053393866, 0.102506867965741307],
    [1.6137278251608962005, 18.422960591455485011, 31.742921188390805758],
    [20.762668673810577145, 2.3614213523314368527, 110.48009643252140334]])


def _ms_coefficients(h, air, aerosol, ozone):
    """(aerosol absorption, aerosol scattering, molecular absorption, molecular
    scattering), each (..., 4) in 1/km, at heights h (...,) km."""
    h = np.asarray(h, np.float64)[..., None]
    a_dens = aerosol * MS_AEROSOL_BASE_DENSITY * (
        np.exp(-h / MS_AEROSOL_HEIGHT_SCALE)
        + MS_AEROSOL_BACKGROUND_DENSITY / MS_AEROSOL_BASE_DENSITY)
    log_h = np.log(np.maximum(h, 1e-4))
    o_dens = 3.78547397e20 * np.exp(-(log_h - 3.22261) ** 2 * 5.55555555 - log_h)
    return (MS_AEROSOL_ABSORPTION * a_dens, MS_AEROSOL_SCATTERING * a_dens,
            ozone * MS_OZONE_CROSS_SECTION * MS_OZONE_DOBSON * o_dens,
            air * MS_MOLECULAR_SCATTERING * np.exp(-0.07771971 * np.power(h, 1.16364243)))


def _ms_extinction(h, air, aerosol, ozone):
    aa, as_, ma, ms = _ms_coefficients(h, air, aerosol, ozone)
    return aa + as_ + ma + ms


def _ms_sphere_hit(r2, b, radius):
    """Blender's ray_sphere_intersection for a point at squared radius r2 (km^2) and a
    unit direction with point . direction = b: the exit distance from inside, the near
    hit from outside, -1 for a miss."""
    c = r2 - radius * radius
    d = b * b - c
    sq = np.sqrt(np.maximum(d, 0.0))
    t = np.where(d >= b * b, -b + sq, -b - sq)
    return np.where(((c > 0) & (b > 0)) | (d < 0), -1.0, t)


def ms_transmittance(cos_theta, normalized_altitude, air=1.0, aerosol=1.0, ozone=1.0):
    """(..., 4) transmittance to the top of the atmosphere from normalized_altitude (0 at
    the ground, 1 at the top) towards a direction of zenith cosine cos_theta: 64
    midpoint steps (Blender's get_transmittance; the Earth is not tested)."""
    c = np.asarray(cos_theta, np.float64)
    r = MS_EARTH_RADIUS + np.asarray(normalized_altitude, np.float64) * MS_THICKNESS
    r, c = np.broadcast_arrays(r, c)
    t_d = _ms_sphere_hit(r * r, r * c, MS_ATMOSPHERE_RADIUS)
    dt = t_d / MS_STEPS
    depth = 0.0
    for i in range(MS_STEPS):
        t = (i + 0.5) * dt
        h = np.maximum(np.sqrt(r * r + t * (2.0 * r * c + t)) - MS_EARTH_RADIUS, 0.0)
        depth = depth + _ms_extinction(h, air, aerosol, ozone) * dt[..., None]
    return np.exp(-depth)


class _MSTransmittance:
    """Blender's 256 x 64 transmittance table (u = cos(sun zenith) 0.5 + 0.5, v =
    normalized altitude, texel i at i / (size - 1)) and its bilinear lookups."""

    def __init__(self, air, aerosol, ozone):
        u = np.arange(MS_LUT_X) / (MS_LUT_X - 1)
        v = np.arange(MS_LUT_Y) / (MS_LUT_Y - 1)
        V, U = np.meshgrid(v, u, indexing="ij")
        self.lut = ms_transmittance(U * 2.0 - 1.0, V, air, aerosol, ozone)  # (64, 256, 4)

    def lookup(self, cos_theta, normalized_altitude):
        x = (MS_LUT_X - 1) * np.clip(cos_theta * 0.5 + 0.5, 0.0, 1.0)
        y = (MS_LUT_Y - 1) * np.clip(normalized_altitude, 0.0, 1.0)
        x1 = x.astype(np.int64)
        y1 = y.astype(np.int64)
        x2 = np.minimum(x1 + 1, MS_LUT_X - 1)
        y2 = np.minimum(y1 + 1, MS_LUT_Y - 1)
        fx = (x - x1)[..., None]
        fy = (y - y1)[..., None]
        flat = self.lut.reshape(-1, 4)  # flat gathers: 2D fancy indexing is much slower
        r1, r2 = y1 * MS_LUT_X, y2 * MS_LUT_X
        a = flat.take(r1 + x1, axis=0)
        bottom = a + fx * (flat.take(r1 + x2, axis=0) - a)
        a = flat.take(r2 + x1, axis=0)
        top = a + fx * (flat.take(r2 + x2, axis=0) - a)
        return bottom + fy * (top - bottom)

    def at_ground(self, cos_theta):
        """lookup(cos_theta, 0): the table's first row."""
        x = (MS_LUT_X - 1) * np.clip(cos_theta * 0.5 + 0.5, 0.0, 1.0)
        x1 = x.astype(np.int64)
        x2 = np.minimum(x1 + 1, MS_LUT_X - 1)
        row = self.lut[0]
        a = row.take(x1, axis=0)
        return a + (x - x1)[..., None] * (row.take(x2, axis=0) - a)

    def to_sun(self, normalized_altitude):
        """lookup(1, normalized_altitude): the table's last column."""
        y = (MS_LUT_Y - 1) * np.clip(normalized_altitude, 0.0, 1.0)
        y1 = y.astype(np.int64)
        y2 = np.minimum(y1 + 1, MS_LUT_Y - 1)
        col = self.lut[:, -1]
        a = col.take(y1, axis=0)
        return a + (y - y1)[..., None] * (col.take(y2, axis=0) - a)

    def multiscattering(self, cos_theta, normalized_altitude, d):
        """(..., 4) multiply scattered light reaching a point at distance d (km) from the
        centre: the ground's second-order light plus the fitted rest of the atmosphere."""
        omega = 2.0 * math.pi * (1.0 - np.sqrt(np.maximum(1.0 - (MS_EARTH_RADIUS / d) ** 2, 0.0)))
        t_ground = self.at_ground(cos_theta)
        t_ground_to_sample = self.lut[0, -1] / self.to_sun(normalized_altitude)
        ground = (1.0 / (4.0 * math.pi)) * omega[..., None] * (MS_GROUND_ALBEDO / math.pi) * \
            t_ground * t_ground_to_sample * cos_theta[..., None]
        fit = 0.02 * np.array([0.217, 0.347, 0.594, 1.0]) * (
            1.0 / (1.0 + 5.0 * np.exp(-17.92 * cos_theta)))[..., None]
        return fit + ground


@functools.lru_cache(maxsize=4)
def _ms_transmittance_table(air, aerosol, ozone):
    """The transmittance table of these densities (it depends on nothing else: a sun or
    altitude change in the viewport reuses it)."""
    return _MSTransmittance(air, aerosol, ozone)


def ms_inscattering(dirs, sun_elevation, altitude, air=1.0, aerosol=1.0, ozone=1.0,
                    transmittance=None):
    """(N, 4) radiance at the four wavelengths along unit directions dirs (N, 3) (the
    sun towards -X at sun_elevation, +Z up) from altitude m: the ray to the ground or to
    the atmosphere's edge in 64 steps (Blender's get_inscattering)."""
    T = transmittance or _ms_transmittance_table(float(air), float(aerosol), float(ozone))
    alt = min(max(altitude, 1.0), 99999.0) / 1000.0
    dirs = np.asarray(dirs, np.float64).reshape(-1, 3)
    c_sun = math.cos(0.5 * math.pi - sun_elevation)
    sun = np.array([-math.sqrt(max(1.0 - c_sun * c_sun, 0.0)), 0.0, c_sun])
    r0 = MS_EARTH_RADIUS + alt
    dz = dirs[:, 2]
    b0 = r0 * dz
    atmos = _ms_sphere_hit(np.full(len(dirs), r0 * r0), b0, MS_ATMOSPHERE_RADIUS)
    ground = _ms_sphere_hit(np.full(len(dirs), r0 * r0), b0, MS_EARTH_RADIUS)
    t_d = np.where(ground < 0.0, atmos, ground)
    cos_t = -(dirs @ sun)
    g2 = MS_G * MS_G
    phase_m = 3.0 / (16.0 * math.pi) * (1.0 + cos_t * cos_t)
    den = 1.0 + g2 + 2.0 * MS_G * cos_t
    phase_a = (1.0 / (4.0 * math.pi)) * (1.0 - g2) / (den * np.sqrt(den))
    dt = t_d / MS_STEPS
    L = np.zeros((len(dirs), 4))
    trans = np.ones((len(dirs), 4))
    for i in range(MS_STEPS):
        t = (i + 0.5) * dt
        # the point r0 z + t d: its distance from the centre and its zenith . sun
        dist = np.sqrt(r0 * r0 + t * (2.0 * b0 + t))
        cos_s = (r0 * sun[2] + t * (dirs @ sun)) / dist
        h = np.maximum(dist - MS_EARTH_RADIUS, 0.0)
        nh = h / MS_THICKNESS
        aa, as_, ma, msc = _ms_coefficients(h, air, aerosol, ozone)
        ext = aa + as_ + ma + msc
        to_sun = T.lookup(cos_s, nh)
        ms = T.multiscattering(cos_s, nh, dist)
        S = MS_SUN_IRRADIANCE * (msc * (phase_m[:, None] * to_sun + ms)
                                 + as_ * (phase_a[:, None] * to_sun + ms))
        step = np.exp(-dt[:, None] * ext)
        L += trans * (S - S * step) / np.maximum(ext, 1e-7)
        trans *= step
    return L


def ms_sky_table(sun_elevation, altitude, air=1.0, aerosol=1.0, ozone=1.0,
                 width=TABLE_WIDTH, height=TABLE_HEIGHT):
    """(height, width, 3) XYZ table of the Multiple Scattering sky as Cycles tabulates
    it: texel (x, y) at azimuth 2 pi (x + 0.5) / width (the sun at the middle column)
    and elevation pi/2 l |l|, l = 2 (y + 0.5) / height - 1 (both hemispheres, dense at
    the horizon), mirrored."""
    half_w = width // 2
    az = 2.0 * math.pi * (np.arange(half_w) + 0.5) / width
    ll = (np.arange(height) + 0.5) / height * 2.0 - 1.0
    el = np.sign(ll) * ll * ll * 0.5 * math.pi
    E, A = np.meshgrid(el, az, indexing="ij")
    dirs = np.stack([np.cos(E) * np.cos(A), np.cos(E) * np.sin(A), np.sin(E)], axis=-1)
    L = ms_inscattering(dirs.reshape(-1, 3), sun_elevation, altitude, air, aerosol, ozone)
    xyz = (L @ MS_SPECTRAL_XYZ).reshape(height, half_w, 3)
    table = np.empty((height, width, 3))
    table[:, :half_w] = xyz
    table[:, width - 1 - np.arange(half_w)] = xyz
    return table


def ms_sun_edges_xyz(sun_elevation, sun_size, altitude, air=1.0, aerosol=1.0, ozone=1.0):
    """XYZ radiance of the Multiple Scattering sun disc at its bottom and top edge: the
    irradiance / the disc's solid angle, times the transmittance towards the edge (not
    clamped at the horizon)."""
    alt = min(max(altitude, 1.0), 99999.0) / 1000.0
    half = sun_size / 2.0
    solid = 2.0 * math.pi * (1.0 - math.cos(half))
    out = []
    for e in (sun_elevation - half, sun_elevation + half):
        T = ms_transmittance(math.cos(0.5 * math.pi - e), alt / MS_THICKNESS, air, aerosol, ozone)
        out.append((MS_SUN_IRRADIANCE * T / solid) @ MS_SPECTRAL_XYZ)
    return out[0], out[1]


def ms_earth_intersection_angle(altitude: float) -> float:
    """Angle (radians) below the horizon where the Earth hides the sky from altitude m
    (Blender's SKY_earth_intersection_angle, Earth radius 6371 km)."""
    return 0.5 * math.pi - math.asin(MS_EARTH_RADIUS / (MS_EARTH_RADIUS + altitude / 1000.0))


# --- Preetham ("A Practical Analytic Model for Daylight", Preetham, Shirley, Smits 1999;
# Cycles' scene/shader_nodes.cpp sky_texture_precompute_preetham, kernel/svm/sky.h) -----

def _perez(lam, theta, gamma):
    """Perez et al.'s sky luminance distribution (5 coefficients lam)."""
    return (1.0 + lam[0] * np.exp(lam[1] / np.cos(theta))) * (
        1.0 + lam[2] * np.exp(lam[3] * gamma) + lam[4] * np.cos(gamma) ** 2)


def preetham_coefficients(sun_theta: float, turbidity: float):
    """(zenith (Y, x, y) / Perez(0, sun_theta), Perez coefficients for Y, x, y (3, 5)) of
    a sun at zenith angle sun_theta and the given turbidity, Cycles' scaling (Y x 0.06)."""
    T, t = turbidity, sun_theta
    t2, t3 = t * t, t * t * t
    chi = (4.0 / 9.0 - T / 120.0) * (math.pi - 2.0 * t)
    Y = ((4.0453 * T - 4.9710) * math.tan(chi) - 0.2155 * T + 2.4192) * 0.06
    x = ((0.00166 * t3 - 0.00375 * t2 + 0.00209 * t) * T * T
         + (-0.02903 * t3 + 0.06377 * t2 - 0.03202 * t + 0.00394) * T
         + (0.11693 * t3 - 0.21196 * t2 + 0.06052 * t + 0.25886))
    y = ((0.00275 * t3 - 0.00610 * t2 + 0.00317 * t) * T * T
         + (-0.04214 * t3 + 0.08970 * t2 - 0.04153 * t + 0.00516) * T
         + (0.15346 * t3 - 0.26756 * t2 + 0.06670 * t + 0.26688))
    lam = np.array([
        [0.1787 * T - 1.4630, -0.3554 * T + 0.4275, -0.0227 * T + 5.3251,
         0.1206 * T - 2.5771, -0.0670 * T + 0.3703],
        [-0.0193 * T - 0.2592, -0.0665 * T + 0.0008, -0.0004 * T + 0.2125,
         -0.0641 * T - 0.8989, -0.0033 * T + 0.0452],
        [-0.0167 * T - 0.2608, -0.0950 * T + 0.0092, -0.0079 * T + 0.2102,
         -0.0441 * T - 1.6537, -0.0109 * T + 0.0529]])
    zenith = np.array([Y, x, y]) / np.array([_perez(lam[i], 0.0, t) for i in range(3)])
    return zenith, lam


def preetham_xyz(d: np.ndarray, sun_vector, turbidity: float) -> np.ndarray:
    """(N, 3) XYZ of the Preetham sky along unit directions d (N, 3) for the node's
    sun_direction vector (normalised, as Blender hands it to Cycles) and turbidity;
    below the horizon the sky just above it (the zenith angle clamped to pi/2 - 0.001)."""
    sv = np.asarray(sun_vector, np.float64)
    sv = sv / max(np.linalg.norm(sv), 1e-300)
    sun_theta = math.acos(min(max(sv[2], -1.0), 1.0))
    sun_phi = math.atan2(sv[0], sv[1])
    zenith, lam = preetham_coefficients(sun_theta, turbidity)
    theta = np.arccos(np.clip(d[:, 2], -1.0, 1.0))
    phi = np.arctan2(d[:, 0], d[:, 1])
    cos_g = (math.sin(sun_theta) * np.sin(theta) * np.cos(phi - sun_phi)
             + math.cos(sun_theta) * np.cos(theta))
    gamma = np.arccos(np.clip(cos_g, -1.0, 1.0))
    theta = np.minimum(theta, 0.5 * math.pi - 0.001)
    Y = zenith[0] * _perez(lam[0], theta, gamma)
    x = zenith[1] * _perez(lam[1], theta, gamma)
    y = zenith[2] * _perez(lam[2], theta, gamma)
    safe = np.where(y != 0, y, 1.0)
    X = np.where(y != 0, x / safe * Y, 0.0)
    Z = np.where((y != 0) & (Y != 0), (1.0 - x - y) / safe * Y, 0.0)
    return np.stack([X, Y, Z], axis=-1)


# --- Hosek / Wilkie ("An Analytic Model for Full Spectral Sky-Dome Radiance", Hosek and
# Wilkie, SIGGRAPH 2012; the CIE XYZ version 1.4a of their reference code, Blender's
# intern/sky/source/sky_hosek.cpp SKY_arhosek_xyz_skymodelstate_alloc_init, as Cycles'
# scene/shader_nodes.cpp sky_texture_precompute_hosek calls it; kernel/svm/sky.h
# sky_radiance_hosek) ------------------------------------------------------------------
# Cycles scales the model's XYZ (W m^-2 sr^-1 x CIE functions, luminance / 683 lm/W) by
# 2 pi / 683 after the RGB conversion.
HOSEK_SCALE = 2.0 * math.pi / 683.0
HOSEK_ZENITH_CLAMP = 0.5 * math.pi - 0.001  # as Preetham: below the horizon the horizon


@functools.lru_cache(maxsize=1)
def hosek_datasets():
    """(XYZ (3, 2, 10, 6, 9), radiance (3, 2, 10, 6)): the model's coefficients per
    channel, ground albedo 0 / 1, turbidity 1..10 and Bezier control point
    (engine/lights/sky_hosek_data.py, (c) Hosek and Wilkie, BSD-3-Clause)."""
    from . import sky_hosek_data as data
    return (np.asarray(data.XYZ, np.float64).reshape(3, 2, 10, 6, 9),
            np.asarray(data.XYZ_RAD, np.float64).reshape(3, 2, 10, 6))


def hosek_cook(dataset: np.ndarray, turbidity: float, albedo: float,
               elevation: float) -> np.ndarray:
    """Blend one channel's dataset (2, 10, 6, ...) for a sun elevation (radians, [0,
    pi/2]), turbidity [1, 10] and ground albedo [0, 1]: a quintic Bezier over
    (elevation / (pi/2))^(1/3) through the 6 control points, linear in albedo between
    the two albedo sets and in turbidity between the integer turbidities around it
    (Hosek and Wilkie's ArHosekSkyModel_CookConfiguration / CookRadianceConfiguration)."""
    t_int = int(turbidity)
    t_rem = turbidity - t_int
    e = (elevation / (0.5 * math.pi)) ** (1.0 / 3.0)
    bezier = np.array([(1.0 - e) ** 5, 5.0 * (1.0 - e) ** 4 * e,
                       10.0 * (1.0 - e) ** 3 * e ** 2, 10.0 * (1.0 - e) ** 2 * e ** 3,
                       5.0 * (1.0 - e) * e ** 4, e ** 5])
    out = ((1.0 - albedo) * (1.0 - t_rem) * np.tensordot(bezier, dataset[0, t_int - 1], 1)
           + albedo * (1.0 - t_rem) * np.tensordot(bezier, dataset[1, t_int - 1], 1))
    if t_int < 10:  # (turbidity 10: nothing above to blend with)
        out = out + ((1.0 - albedo) * t_rem * np.tensordot(bezier, dataset[0, t_int], 1)
                     + albedo * t_rem * np.tensordot(bezier, dataset[1, t_int], 1))
    return out


def hosek_state(sun_vector, turbidity: float, albedo: float):
    """(sun zenith angle, sun azimuth phi = atan2(x, y), configs (3, 9), radiances (3,))
    as Cycles precomputes them: the sun clamped to [0, pi/2] from the zenith (a sun below
    the horizon lights the sky as one on it), turbidity clamped to [1, 10] (Cycles clamps
    to [0, 10]; the node's range is [1, 10] and below 1 the reference code reads outside
    its table)."""
    sv = np.asarray(sun_vector, np.float64)
    sv = sv / max(np.linalg.norm(sv), 1e-300)
    theta = min(max(math.acos(min(max(sv[2], -1.0), 1.0)), 0.0), 0.5 * math.pi)
    phi = math.atan2(sv[0], sv[1])
    turbidity = min(max(float(turbidity), 1.0), 10.0)
    elevation = 0.5 * math.pi - theta
    xyz, rad = hosek_datasets()
    configs = np.stack([hosek_cook(xyz[c], turbidity, albedo, elevation) for c in range(3)])
    radiances = np.array([float(hosek_cook(rad[c], turbidity, albedo, elevation))
                          for c in range(3)])
    return theta, phi, configs, radiances


def hosek_radiance(config: np.ndarray, theta: np.ndarray, gamma: np.ndarray) -> np.ndarray:
    """The model's sky-dome distribution F(theta, gamma) for one channel's 9 parameters
    A..I at view zenith angles theta and angles gamma from the sun (radians):
    (1 + A exp(B / (cos theta + 0.01))) (C + D exp(E gamma) + F cos^2 gamma
    + G (1 + cos^2 gamma) / (1 + I^2 - 2 I cos gamma)^1.5 + H sqrt(cos theta))."""
    A, B, C, D, E, F, G, H, I = config
    ct, cg = np.cos(theta), np.cos(gamma)
    mie = (1.0 + cg * cg) / (1.0 + I * I - 2.0 * I * cg) ** 1.5
    return (1.0 + A * np.exp(B / (ct + 0.01))) * (
        C + D * np.exp(E * gamma) + F * cg * cg + G * mie + H * np.sqrt(ct))


def hosek_xyz(d: np.ndarray, sun_vector, turbidity: float, albedo: float) -> np.ndarray:
    """(N, 3) XYZ of the Hosek / Wilkie sky x Cycles' 2 pi / 683 along unit directions
    d (N, 3) for the node's sun_direction (normalised, as Blender hands it to Cycles),
    turbidity and ground albedo; gamma from the true direction, theta then clamped to
    pi/2 - 0.001 (below the horizon the horizon's colour)."""
    sun_theta, sun_phi, configs, radiances = hosek_state(sun_vector, turbidity, albedo)
    theta = np.arccos(np.clip(d[:, 2], -1.0, 1.0))
    phi = np.arctan2(d[:, 0], d[:, 1])
    cos_g = (math.sin(sun_theta) * np.sin(theta) * np.cos(phi - sun_phi)
             + math.cos(sun_theta) * np.cos(theta))
    gamma = np.arccos(np.clip(cos_g, -1.0, 1.0))
    theta = np.minimum(theta, HOSEK_ZENITH_CLAMP)
    return np.stack([hosek_radiance(configs[c], theta, gamma) * radiances[c]
                     for c in range(3)], axis=-1) * HOSEK_SCALE


# --- the node ---------------------------------------------------------------------------

@dataclass
class SkyTexture:
    """A Sky Texture node's settings (Blender's names and units: angles in radians,
    altitude in m, densities relative to Earth's). sky_type: SKY_TYPES (or 4.x's NISHITA).
    Preetham and Hosek / Wilkie read only sun_vector, turbidity (and Hosek / Wilkie
    ground_albedo) and have no disc.
    strength: the Background node's strength (scalar or RGB)."""

    sky_type: str = "SINGLE_SCATTERING"
    sun_disc: bool = True
    sun_size: float = math.radians(0.545)
    sun_intensity: float = 1.0
    sun_elevation: float = math.radians(15.0)
    sun_rotation: float = 0.0
    altitude: float = 100.0
    air_density: float = 1.0
    aerosol_density: float = 1.0
    ozone_density: float = 1.0
    # Preetham and Hosek / Wilkie: the node's sun_direction (a vector) and turbidity;
    # Hosek / Wilkie's ground albedo in [0, 1]
    sun_vector: tuple = (0.0, 0.0, 1.0)
    turbidity: float = 2.2
    ground_albedo: float = 0.3
    strength: object = 1.0
    rotation: np.ndarray | None = None
    name: str = "sky"
    # Cycles' table size; smaller only to test quickly
    table_size: tuple = (TABLE_WIDTH, TABLE_HEIGHT)
    _table: np.ndarray | None = field(default=None, repr=False)

    def __post_init__(self):
        self.sky_type = SKY_TYPE_ALIASES.get(str(self.sky_type).upper(), str(self.sky_type).upper())
        who = f"sky '{self.name}'"
        if self.sky_type not in SUPPORTED_SKY_TYPES:
            raise ValueError(f"{who}: sky type {self.sky_type} is not supported (only "
                             f"{', '.join(SUPPORTED_SKY_TYPES)})")
        for key in ("sun_size", "sun_intensity", "sun_elevation", "sun_rotation", "altitude",
                    "air_density", "aerosol_density", "ozone_density", "turbidity",
                    "ground_albedo"):
            v = getattr(self, key)
            if not math.isfinite(float(v)):
                raise ValueError(f"{who} {key}: expected a finite number, got {v!r}")
            setattr(self, key, float(v))
        for key in ("sun_size", "sun_intensity", "air_density", "aerosol_density",
                    "ozone_density"):
            if getattr(self, key) < 0:
                raise ValueError(f"{who} {key}: expected a value >= 0, got {getattr(self, key)}")
        if not 0.0 <= self.ground_albedo <= 1.0:
            raise ValueError(f"{who} ground_albedo: expected a value in [0, 1], got "
                             f"{self.ground_albedo}")
        v = np.asarray(self.sun_vector, np.float64).reshape(-1)
        if v.shape != (3,) or not np.all(np.isfinite(v)):
            raise ValueError(f"{who} sun_vector: expected 3 finite numbers, got {self.sun_vector!r}")
        self.sun_vector = v
        self.elevation, self.azimuth = self._sun_position()

    def _sun_position(self):
        """(elevation in [-pi/2, pi/2], rotation) as Cycles folds an animated sun
        (SkyTextureNode::simplify_settings): an elevation past the zenith turns the sun
        round by pi."""
        e = math.fmod(self.sun_elevation, 2.0 * math.pi)
        r = self.sun_rotation
        if abs(e) >= math.pi:
            e -= math.copysign(2.0 * math.pi, e)
        if e >= 0.5 * math.pi or e <= -0.5 * math.pi:
            e = math.copysign(math.pi, e) - e
            r += math.pi
        return e, r

    @property
    def sun_size_clamped(self) -> float:
        return max(self.sun_size, MIN_SUN_SIZE)

    def sun_direction(self) -> np.ndarray:
        """Unit direction towards the sun's centre in texture space (sun_rotation 0: +Y,
        turning towards +X)."""
        e, r = self.elevation, self.azimuth
        return np.array([math.cos(e) * math.sin(r), math.cos(e) * math.cos(r), math.sin(e)])

    @property
    def table(self) -> np.ndarray:
        if self._table is None:
            build = ms_sky_table if self.multiple_scattering else sky_table
            self._table = build(self.elevation, self.altitude, self.air_density,
                                self.aerosol_density, self.ozone_density, *self.table_size)
        return self._table

    @property
    def multiple_scattering(self) -> bool:
        return self.sky_type == "MULTIPLE_SCATTERING"

    def sky_xyz(self, d: np.ndarray) -> np.ndarray:
        """(N, 3) XYZ radiance of the sky without the sun disc along texture-space
        directions d (N, 3) (unit or not), as Cycles looks its table up."""
        d = np.asarray(d, np.float64).reshape(-1, 3)
        d = d / np.maximum(np.linalg.norm(d, axis=1, keepdims=True), 1e-300)
        if self.sky_type == "PREETHAM":
            return preetham_xyz(d, self.sun_vector, self.turbidity)
        if self.sky_type == "HOSEK_WILKIE":
            return hosek_xyz(d, self.sun_vector, self.turbidity, self.ground_albedo)
        z = np.clip(d[:, 2], -1.0, 1.0)
        elev = np.arcsin(z)
        # longitude relative to the sun: the table's x = 0.5 looks at the sun
        sun = self.sun_direction()
        phi = np.arctan2(d[:, 1], d[:, 0]) - math.atan2(sun[1], sun[0])
        x = np.mod(phi / (2.0 * math.pi) + 0.5, 1.0)
        y = np.sqrt(np.abs(elev) / (0.5 * math.pi)) * np.sign(elev) * 0.5 + 0.5
        return _table_lookup(self.table, x, y)

    def sky_rgb(self, d: np.ndarray) -> np.ndarray:
        """(N, 3) linear Rec.709 radiance of the sky (no sun disc) x strength along
        texture-space directions d (N, 3)."""
        s = np.broadcast_to(np.asarray(self.strength, np.float64), (3,))
        return xyz_to_rec709(self.sky_xyz(d)) * s

    def sun_rgb(self, d: np.ndarray) -> np.ndarray:
        """(N, 3) radiance of the sun disc (x sun_intensity x strength) along texture-space
        unit directions d (N, 3); 0 outside the disc, below the horizon or with the disc
        off."""
        d = np.asarray(d, np.float64).reshape(-1, 3)
        out = np.zeros((len(d), 3))
        if not self.sun_disc or self.sky_type in ANALYTIC_SKY_TYPES:  # they have no disc
            return out
        size = self.sun_size_clamped
        half = 0.5 * size
        sun = self.sun_direction()
        angle = np.arccos(np.clip(d @ sun, -1.0, 1.0))
        elev = np.arcsin(np.clip(d[:, 2], -1.0, 1.0))
        # Seen down to the Earth's limb (Single Scattering's edges are black once the
        # disc's top is below the horizon).
        inside = (angle < half) & (elev > -ms_earth_intersection_angle(self.altitude))
        if not inside.any():
            return out
        if self.multiple_scattering:
            bottom, top = ms_sun_edges_xyz(self.elevation, size, self.altitude,
                                           self.air_density, self.aerosol_density,
                                           self.ozone_density)
        else:
            bottom, top = sun_edges_xyz(self.elevation, size, self.altitude, self.air_density,
                                        self.aerosol_density)
        t = ((elev[inside] - self.elevation) / size + 0.5)[:, None]
        xyz = bottom + t * (top - bottom)
        limb = 1.0 - LIMB_DARKENING * (1.0 - np.sqrt(1.0 - (angle[inside] / half) ** 2))
        s = np.broadcast_to(np.asarray(self.strength, np.float64), (3,))
        out[inside] = xyz_to_rec709(xyz) * limb[:, None] * self.sun_intensity * s
        return out

    def sun_irradiance(self, n: int = 96) -> np.ndarray:
        """RGB irradiance (W / m^2) of the sun disc on a surface facing it: the disc's
        radiance integrated over its solid angle (a midpoint rule on n x n points of the
        disc's tangent plane, mapped to equal solid angles)."""
        if not self.sun_disc or self.sky_type in ANALYTIC_SKY_TYPES:
            return np.zeros(3)
        half = 0.5 * self.sun_size_clamped
        sun = self.sun_direction()
        up = np.array([0.0, 0.0, 1.0]) if abs(sun[2]) < 0.999 else np.array([1.0, 0.0, 0.0])
        t = np.cross(up, sun)
        t /= np.linalg.norm(t)
        b = np.cross(sun, t)
        g = (np.arange(n) + 0.5) / n * 2.0 - 1.0
        gx, gy = np.meshgrid(g, g, indexing="ij")
        r2 = gx * gx + gy * gy
        keep = r2 < 1.0
        # a point at radius r of the unit disc: cos(angle) = 1 - r^2 (1 - cos half), equal
        # areas of the disc -> equal solid angles of the cap
        cos_a = 1.0 - r2[keep] * (1.0 - math.cos(half))
        sin_a = np.sqrt(np.maximum(1.0 - cos_a * cos_a, 0.0))
        rr = np.sqrt(r2[keep])
        ux = np.where(rr > 0, gx[keep] / np.maximum(rr, 1e-300), 1.0)
        uy = np.where(rr > 0, gy[keep] / np.maximum(rr, 1e-300), 0.0)
        d = (cos_a[:, None] * sun + (sin_a * ux)[:, None] * t + (sin_a * uy)[:, None] * b)
        solid = 2.0 * math.pi * (1.0 - math.cos(half))
        # each kept cell covers solid / (pi n^2 / 4) of the cap
        return self.sun_rgb(d).sum(axis=0) * solid * 4.0 / (math.pi * n * n)

    def bake(self, width: int = BAKE_WIDTH, height: int = BAKE_HEIGHT) -> np.ndarray:
        """(height, width, 3) float32 equirectangular radiance of the sky without the sun
        disc, x strength, in the Environment's layout (engine/lights/environment.py)."""
        theta = math.pi * (np.arange(height) + 0.5) / height
        u = (np.arange(width) + 0.5) / width
        phi = 2.0 * math.pi * (0.5 - u)
        th, ph = np.meshgrid(theta, phi, indexing="ij")
        d = np.stack([np.sin(th) * np.cos(ph), np.sin(th) * np.sin(ph), np.cos(th)], axis=-1)
        return self.sky_rgb(d.reshape(-1, 3)).reshape(height, width, 3).astype(np.float32)

    def environment(self, width: int = BAKE_WIDTH, height: int = BAKE_HEIGHT):
        """The engine Environment of the sky (without the sun disc); its `sun_light` is
        sun_light_params() and its `sky` this SkyTexture."""
        from .environment import Environment
        env = Environment(self.bake(width, height), 1.0, self.rotation, "Linear",
                          name=self.name)
        env.sky = self
        env.sun_light = self.sun_light_params()
        return env

    def sun_light_params(self):
        """None (disc off, or below the horizon) or a dict for engine/scene.py Light:
        kind SUN, direction of travel in world space, power 1 x colour = the disc's RGB
        irradiance, angle = sun_size; seen by camera rays as Cycles' sky shows its disc."""
        E = self.sun_irradiance()
        if not np.any(E > 0):
            return None
        d = self.sun_direction()
        if self.rotation is not None:
            d = np.asarray(self.rotation, np.float64).T @ d  # texture -> world
        return dict(kind="SUN", power=1.0, color=E, direction=-d, angle=self.sun_size_clamped,
                    visible_camera=True, name=f"{self.name} sun")

"""Many lights: choose one light per shadow ray by its importance at the shading point, so
the cost of direct light per sample stays flat however many lights a scene has.

The chooser is a light tree (a bounding volume hierarchy over the lights), as Cycles'
kernel/light/tree.h and pbrt-v4's BVHLightSampler (lightsamplers.h / .cpp) do: every node
bounds its lights' positions (a box), emission directions (a cone of normals `w`,
half-angle theta_o, plus theta_e beyond it that emission can reach) and total power
`phi`. A shading point walks down from the root, taking each child with probability
proportional to its importance

    importance = phi x cos(theta') / d^2 x cos(theta_i')      (pbrt-v4 LightBounds)

theta' = max(0, theta_w - theta_o - theta_b): the angle between the node's cone and the
direction to the point, less what the box subtends; theta_i' likewise at the point's
normal; zero when theta' >= theta_e. The bounds are conservative, so every light that can
light a point keeps a non-zero probability: the estimator contribution / pmf is unbiased.
Lights at infinity (sun, world) sit beside the tree's root, each with the importance
4 pi x the irradiance it can bring (the sun: strength x cos(theta_i') within its disk;
the world: pi x its mean luminance), the scale of the tree's point lights (phi = 4 pi I),
so a dim world does not take half the samples of a scene of bright lamps (pbrt-v4 gives
lights at infinity a fixed share; Cycles' tree weighs them by energy too).

`LightSelector.pmf` gives the probability of choosing a given light at a point, the
factor a BSDF-sampled ray that meets a light needs for multiple importance sampling.
When a scene has at most SAMPLE_ALL_UP_TO lights, every light gets its own shadow rays
instead (lower noise per sample, as before the tree); above it, `light_samples` shadow
rays per sample go to lights the tree picks (engine/integrator.direct_irradiance).
"""
from __future__ import annotations

import math

import numpy as np

from ..jit import kernel, register_warm_up
from ..sampling import luminance
from .mesh import MESH
from .sun import SunLight
from .world import WorldLight

# Scenes with more lights than this sample them through the tree.
SAMPLE_ALL_UP_TO = 16

# Float columns of a tree node: box lo (3), hi (3), cone axis w (3), cos theta_o,
# cos theta_e, phi (power), two-sided flag.
LO, HI, W, COS_O, COS_E, PHI, TWO = 0, 3, 6, 9, 10, 11, 12
NF = 13
# Integer columns: children (-1: leaf), the leaf's light, the parent (-1: root).
C0, C1, LIGHT, PARENT = 0, 1, 2, 3
NI = 4
# Columns of a light at infinity: direction towards it (3), cos of its disk's half angle
# (-1: all directions), 4 pi x its largest irradiance.
IW, ICOS, IE = 0, 3, 4
NINF = 5


def light_bounds(light):
    """(lo (3,), hi (3,), w (3,), cos_theta_o, cos_theta_e, phi, two_sided) of a finite
    light (engine/lights/ kinds), pbrt-v4's Light::Bounds() in our units."""
    kind = light.kind
    if kind in ("POINT", "SPOT"):
        r = float(light.radius)
        lo, hi = light.pos - r, light.pos + r
        phi = 4.0 * math.pi * float(luminance(np.asarray(light.intensity)))
        if kind == "SPOT":
            # The cone holding the whole (possibly scaled) spot; nothing beyond it.
            cos_o = float(np.clip(light.spot_cos_bound, -1.0, 1.0))
            return lo, hi, np.asarray(light.dir, float), cos_o, 0.0, phi, False
        return lo, hi, np.array([0.0, 0.0, 1.0]), -1.0, 0.0, phi, False
    if kind == "AREA":
        hx, hy = 0.5 * light.size_x, 0.5 * light.size_y
        corners = [light.pos + sx * hx * a + sy * hy * b for a, b in ((light.u, light.v),
                                                                     (light.du, light.dv))
                   for sx in (-1, 1) for sy in (-1, 1)]
        corners = np.array(corners)
        phi = math.pi * light.area * float(luminance(np.asarray(light.radiance)))
        # One-sided along dir; spread only narrows emission inside the hemisphere.
        return (corners.min(axis=0), corners.max(axis=0), np.asarray(light.dir, float),
                1.0, 0.0, phi, False)
    if kind == MESH:
        # The root of the light's own triangle tree (MeshLight.triangle_tree): its box
        # and its triangles' cone of normals (two-sided), the power of the whole light.
        root = light.triangle_tree()[0][0]
        phi = float(luminance(np.asarray(light.photon_flux)))
        return (root[LO:LO + 3].copy(), root[HI:HI + 3].copy(), root[W:W + 3].copy(),
                float(root[COS_O]), float(root[COS_E]), phi, True)
    raise ValueError(f"light '{light.name}': kind {kind} has no bounds for the light tree")


def _cone_union(wa, ca, wb, cb):
    """Smallest cone holding cones (wa, cos ca) and (wb, cos cb): pbrt-v4 DirectionCone
    Union. Returns (w (3,), cos theta). Plain floats: the build runs once per light."""
    ax, ay, az = (float(c) for c in wa)
    bx, by, bz = (float(c) for c in wb)
    ta = math.acos(min(max(float(ca), -1.0), 1.0))
    tb = math.acos(min(max(float(cb), -1.0), 1.0))
    td = math.acos(min(max(ax * bx + ay * by + az * bz, -1.0), 1.0))
    if min(td + tb, math.pi) <= ta:
        return wa, ca
    if min(td + ta, math.pi) <= tb:
        return wb, cb
    to = (ta + td + tb) / 2.0
    if to >= math.pi:
        return wa, -1.0
    tr = to - ta
    kx, ky, kz = ay * bz - az * by, az * bx - ax * bz, ax * by - ay * bx
    n = math.sqrt(kx * kx + ky * ky + kz * kz)
    if n < 1e-12:
        return wa, -1.0
    kx, ky, kz = kx / n, ky / n, kz / n
    # Rodrigues: wa turned about k by tr (k is normal to wa).
    c, s = math.cos(tr), math.sin(tr)
    cx, cy, cz = ky * az - kz * ay, kz * ax - kx * az, kx * ay - ky * ax
    w = np.array([ax * c + cx * s, ay * c + cy * s, az * c + cz * s])
    return w / np.linalg.norm(w), math.cos(to)


def build_tree(lo, hi, w, cos_o, cos_e, phi, two):
    """A light tree over N emitters given by their bounds (lo, hi (N,3) box, w (N,3) unit
    cone axis, cos_o (N,) cos theta_o, cos_e (N,) cos theta_e, phi (N,) power, two (N,)
    bool two-sided): (tree_f (2N-1, NF), tree_i (2N-1, NI) with LIGHT = the emitter's
    index, leaf_of (N,) each emitter's leaf), in LightSelector's layout, the root first
    and each node before its children; split at the median of the widest axis of the
    centres, as LightSelector. Used for the triangles of a mesh light (Cycles puts every
    emissive triangle into its light tree: kernel/light/tree.h), which select_light and
    light_pmf then walk with empty lights at infinity."""
    N = len(phi)
    tf = np.zeros((max(2 * N - 1, 0), NF))
    ti = np.full((max(2 * N - 1, 0), NI), -1, np.int64)
    leaf_of = np.full(N, -1, np.int64)
    centres = 0.5 * (lo + hi)
    leaves = np.concatenate([lo, hi, w, cos_o[:, None], cos_e[:, None], phi[:, None],
                             np.asarray(two, float)[:, None]], axis=1)
    count = [0]

    def rec(idx, parent):
        node = count[0]
        count[0] += 1
        ti[node, PARENT] = parent
        if len(idx) == 1:
            k = int(idx[0])
            tf[node] = leaves[k]
            ti[node, LIGHT] = k
            leaf_of[k] = node
            return node
        c = centres[idx]
        axis = int(np.argmax(c.max(axis=0) - c.min(axis=0)))
        order = np.argsort(c[:, axis], kind="stable")
        half = len(idx) // 2
        a = rec(idx[order[:half]], node)
        b = rec(idx[order[half:]], node)
        fa, fb = tf[a], tf[b]
        wu, cu = _cone_union(fa[W:W + 3], fa[COS_O], fb[W:W + 3], fb[COS_O])
        tf[node, LO:LO + 3] = np.minimum(fa[LO:LO + 3], fb[LO:LO + 3])
        tf[node, HI:HI + 3] = np.maximum(fa[HI:HI + 3], fb[HI:HI + 3])
        tf[node, W:W + 3] = wu
        tf[node, COS_O] = cu
        tf[node, COS_E] = min(fa[COS_E], fb[COS_E])
        tf[node, PHI] = fa[PHI] + fb[PHI]
        tf[node, TWO] = max(fa[TWO], fb[TWO])
        ti[node, C0], ti[node, C1] = a, b
        return node

    if N:
        rec(np.arange(N), -1)
    return np.ascontiguousarray(tf), np.ascontiguousarray(ti), leaf_of


class LightSelector:
    """The light tree over a list of prepared lights (indices into it: `members`).

    tree_f (M, NF) float64, tree_i (M, NI) int64: nodes, the root first; infinite (I,)
    int64, inf_f (I, NINF): the lights at infinity; leaf_of (L,) int64: each light's leaf (-1: infinite or
    not a member). Build once per render (prepare_lights' order)."""

    def __init__(self, lights, members):
        self.members = np.asarray(members, np.int64)
        finite, infinite = [], []
        for li in self.members:
            (infinite if isinstance(lights[li], (SunLight, WorldLight)) else finite).append(li)
        self.infinite = np.asarray(infinite, np.int64)
        inf_f = np.zeros((len(infinite), NINF))
        for j, li in enumerate(infinite):
            light = lights[li]
            if isinstance(light, SunLight):
                inf_f[j, IW:IW + 3] = -np.asarray(light.dir, float)
                inf_f[j, ICOS] = light.cos_half_angle
                E = float(luminance(np.asarray(light.irradiance)))
            else:
                inf_f[j, IW:IW + 3] = (0.0, 0.0, 1.0)
                inf_f[j, ICOS] = -1.0
                E = math.pi * float(luminance(np.asarray(light.radiance)))
            inf_f[j, IE] = 4.0 * math.pi * max(E, 1e-30)
        self.inf_f = np.ascontiguousarray(inf_f)
        self.leaf_of = np.full(len(lights), -1, np.int64)
        rows_f, rows_i = [], []
        if finite:
            bounds = {li: light_bounds(lights[li]) for li in finite}
            self._build(finite, bounds, -1, rows_f, rows_i)
        self.tree_f = np.ascontiguousarray(np.array(rows_f, np.float64).reshape(-1, NF))
        self.tree_i = np.ascontiguousarray(np.array(rows_i, np.int64).reshape(-1, NI))
        self.finite = np.asarray(finite, np.int64)

    def _build(self, items, bounds, parent, rows_f, rows_i) -> int:
        """Append the subtree of lights `items`; returns its node index. Splits at the
        median of the widest axis of the lights' centres."""
        node = len(rows_f)
        rows_f.append(np.zeros(NF))
        rows_i.append(np.array([-1, -1, -1, parent], np.int64))
        if len(items) == 1:
            li = items[0]
            lo, hi, w, cos_o, cos_e, phi, two = bounds[li]
            rows_f[node] = np.concatenate([lo, hi, w, [cos_o, cos_e, phi, float(two)]])
            rows_i[node][LIGHT] = li
            self.leaf_of[li] = node
            return node
        centres = np.array([(bounds[li][0] + bounds[li][1]) / 2 for li in items])
        axis = int(np.argmax(centres.max(axis=0) - centres.min(axis=0)))
        order = np.argsort(centres[:, axis], kind="stable")
        half = len(items) // 2
        left = [items[k] for k in order[:half]]
        right = [items[k] for k in order[half:]]
        a = self._build(left, bounds, node, rows_f, rows_i)
        b = self._build(right, bounds, node, rows_f, rows_i)
        fa, fb = rows_f[a], rows_f[b]
        w, cos_o = _cone_union(fa[W:W + 3], fa[COS_O], fb[W:W + 3], fb[COS_O])
        rows_f[node] = np.concatenate([np.minimum(fa[LO:LO + 3], fb[LO:LO + 3]),
                                       np.maximum(fa[HI:HI + 3], fb[HI:HI + 3]), w,
                                       [cos_o, min(fa[COS_E], fb[COS_E]),
                                        fa[PHI] + fb[PHI], max(fa[TWO], fb[TWO])]])
        rows_i[node][C0], rows_i[node][C1] = a, b
        return node

    # ------------------------------------------------------------------ numpy front ends
    def select(self, p, n, u):
        """Lights chosen at points p (N,3) with normals n (N,3) from uniform numbers u (N,):
        (light index (N,) int64, -1 where no light can contribute; pmf (N,))."""
        p, n = (np.ascontiguousarray(a, np.float64).reshape(-1, 3) for a in (p, n))
        u = np.ascontiguousarray(u, np.float64)
        li = np.empty(len(u), np.int64)
        pmf = np.empty(len(u))
        select_many(p, n, u, self.tree_f, self.tree_i, self.infinite, self.inf_f, li, pmf)
        return li, pmf

    def pmf(self, p, n, light_index: int):
        """Probability (N,) of choosing light `light_index` (an index into the prepared
        lights) at points p (N,3) with normals n (N,3): the light-selection factor of the
        light-sampling pdf for multiple importance sampling (0 for a light not in the
        selector)."""
        p, n = (np.ascontiguousarray(a, np.float64).reshape(-1, 3) for a in (p, n))
        out = np.empty(len(p))
        pmf_many(p, n, int(light_index), self.tree_f, self.tree_i, self.infinite, self.inf_f,
                 self.leaf_of, out)
        return out


# ---------------------------------------------------------------------- kernels
@kernel
def _cos_sub_clamped(sin_a, cos_a, sin_b, cos_b):
    """cos(max(0, a - b))."""
    if cos_a > cos_b:
        return 1.0
    return cos_a * cos_b + sin_a * sin_b


@kernel
def _sin_sub_clamped(sin_a, cos_a, sin_b, cos_b):
    """sin(max(0, a - b))."""
    if cos_a > cos_b:
        return 0.0
    return sin_a * cos_b - cos_a * sin_b


@kernel
def node_importance(tf, k, p0, p1, p2, n0, n1, n2):
    """Importance of node k of tree_f `tf` at point p with normal n (pbrt-v4
    LightBounds::Importance; n = 0: no normal)."""
    c0 = 0.5 * (tf[k, LO] + tf[k, HI])
    c1 = 0.5 * (tf[k, LO + 1] + tf[k, HI + 1])
    c2 = 0.5 * (tf[k, LO + 2] + tf[k, HI + 2])
    x0, x1, x2 = p0 - c0, p1 - c1, p2 - c2
    d2 = x0 * x0 + x1 * x1 + x2 * x2
    e0 = tf[k, HI] - tf[k, LO]
    e1 = tf[k, HI + 1] - tf[k, LO + 1]
    e2 = tf[k, HI + 2] - tf[k, LO + 2]
    r2 = 0.25 * (e0 * e0 + e1 * e1 + e2 * e2)  # bounding sphere radius^2 of the box
    d = math.sqrt(d2)
    if d > 0:
        wi0, wi1, wi2 = x0 / d, x1 / d, x2 / d
    else:
        wi0, wi1, wi2 = 0.0, 0.0, 1.0
    # Inside the box's bounding sphere: every direction is possible.
    if d2 <= r2:
        cos_b = -1.0
    else:
        cos_b = math.sqrt(max(0.0, 1.0 - r2 / d2))
    sin_b = math.sqrt(max(0.0, 1.0 - cos_b * cos_b))
    dd = max(d2, r2)
    cos_w = tf[k, W] * wi0 + tf[k, W + 1] * wi1 + tf[k, W + 2] * wi2
    if tf[k, TWO] != 0.0:
        cos_w = abs(cos_w)
    sin_w = math.sqrt(max(0.0, 1.0 - cos_w * cos_w))
    cos_o = tf[k, COS_O]
    sin_o = math.sqrt(max(0.0, 1.0 - cos_o * cos_o))
    cos_x = _cos_sub_clamped(sin_w, cos_w, sin_o, cos_o)
    sin_x = _sin_sub_clamped(sin_w, cos_w, sin_o, cos_o)
    cos_p = _cos_sub_clamped(sin_x, cos_x, sin_b, cos_b)
    if cos_p <= tf[k, COS_E]:
        return 0.0
    imp = tf[k, PHI] * cos_p / max(dd, 1e-300)
    if n0 != 0.0 or n1 != 0.0 or n2 != 0.0:
        cos_i = abs(wi0 * n0 + wi1 * n1 + wi2 * n2)
        sin_i = math.sqrt(max(0.0, 1.0 - cos_i * cos_i))
        imp *= _cos_sub_clamped(sin_i, cos_i, sin_b, cos_b)
    return max(imp, 0.0)


@kernel
def infinite_importance(inf_f, j, n0, n1, n2):
    """Importance of light at infinity j at a point with normal n (0: no normal)."""
    imp = inf_f[j, IE]
    if inf_f[j, ICOS] > -1.0 and (n0 != 0.0 or n1 != 0.0 or n2 != 0.0):
        cos_i = abs(inf_f[j, IW] * n0 + inf_f[j, IW + 1] * n1 + inf_f[j, IW + 2] * n2)
        sin_i = math.sqrt(max(0.0, 1.0 - cos_i * cos_i))
        cb = inf_f[j, ICOS]
        imp *= _cos_sub_clamped(sin_i, cos_i, math.sqrt(max(0.0, 1.0 - cb * cb)), cb)
    return max(imp, 0.0)


@kernel
def _root_weights(tf, inf_f, p0, p1, p2, n0, n1, n2):
    """(importance of the tree's root or 0, sum over the lights at infinity)."""
    tree = node_importance(tf, 0, p0, p1, p2, n0, n1, n2) if tf.shape[0] > 0 else 0.0
    s_inf = 0.0
    for j in range(inf_f.shape[0]):
        s_inf += infinite_importance(inf_f, j, n0, n1, n2)
    return tree, s_inf


@kernel
def select_light(tf, ti, infinite, inf_f, p0, p1, p2, n0, n1, n2, u):
    """(light index or -1, pmf, u remapped to [0, 1) for the light's own use)."""
    tree, s_inf = _root_weights(tf, inf_f, p0, p1, p2, n0, n1, n2)
    total = tree + s_inf
    if not total > 0:
        return -1, 0.0, u
    x = u * total
    if x < s_inf:
        acc = 0.0
        last = -1
        for j in range(inf_f.shape[0]):
            w = infinite_importance(inf_f, j, n0, n1, n2)
            if w > 0:
                last = j
                if x < acc + w:
                    return infinite[j], w / total, min((x - acc) / w, 0.9999999999999999)
                acc += w
        if last >= 0 and tree <= 0:  # rounding at the top end
            w = infinite_importance(inf_f, last, n0, n1, n2)
            return infinite[last], w / total, 0.9999999999999999
    if not tree > 0:
        return -1, 0.0, u
    u = min(max(x - s_inf, 0.0) / tree, 0.9999999999999999)
    pmf = tree / total
    k = 0
    while ti[k, C0] >= 0:
        a = ti[k, C0]
        b = ti[k, C1]
        ia = node_importance(tf, a, p0, p1, p2, n0, n1, n2)
        ib = node_importance(tf, b, p0, p1, p2, n0, n1, n2)
        s = ia + ib
        if not s > 0:
            return -1, 0.0, u
        pa = ia / s
        if u < pa:
            u = min(u / pa, 0.9999999999999999)
            pmf *= pa
            k = a
        else:
            u = min((u - pa) / (1.0 - pa), 0.9999999999999999)
            pmf *= 1.0 - pa
            k = b
    return ti[k, LIGHT], pmf, u


@kernel
def light_pmf(tf, ti, infinite, inf_f, leaf_of, li, p0, p1, p2, n0, n1, n2):
    """Probability that select_light picks light li at p with normal n."""
    tree, s_inf = _root_weights(tf, inf_f, p0, p1, p2, n0, n1, n2)
    total = tree + s_inf
    if not total > 0:
        return 0.0
    for j in range(infinite.shape[0]):
        if infinite[j] == li:
            return infinite_importance(inf_f, j, n0, n1, n2) / total
    if not tree > 0 or li < 0 or li >= leaf_of.shape[0] or leaf_of[li] < 0:
        return 0.0
    pmf = tree / total
    k = leaf_of[li]
    while ti[k, PARENT] >= 0:
        parent = ti[k, PARENT]
        a = ti[parent, C0]
        b = ti[parent, C1]
        ia = node_importance(tf, a, p0, p1, p2, n0, n1, n2)
        ib = node_importance(tf, b, p0, p1, p2, n0, n1, n2)
        s = ia + ib
        if not s > 0:
            return 0.0
        pmf *= (ia if k == a else ib) / s
        k = parent
    return pmf


@kernel
def select_many(p, n, u, tf, ti, infinite, inf_f, li, pmf):
    for i in range(p.shape[0]):
        li[i], pmf[i], _ = select_light(tf, ti, infinite, inf_f, p[i, 0], p[i, 1], p[i, 2],
                                        n[i, 0], n[i, 1], n[i, 2], u[i])


@kernel
def pmf_many(p, n, light, tf, ti, infinite, inf_f, leaf_of, out):
    for i in range(p.shape[0]):
        out[i] = light_pmf(tf, ti, infinite, inf_f, leaf_of, light, p[i, 0], p[i, 1],
                           p[i, 2], n[i, 0], n[i, 1], n[i, 2])


@kernel
def pmf_each(p, n, which, tf, ti, leaf_of, out):
    """out[i]: probability that select_light (no lights at infinity) picks emitter
    which[i] of tree (tf, ti, leaf_of: build_tree) at point p[i] with normal n[i]."""
    no_inf = np.zeros(0, np.int64)
    no_inf_f = np.zeros((0, NINF))
    for i in range(p.shape[0]):
        out[i] = light_pmf(tf, ti, no_inf, no_inf_f, leaf_of, which[i], p[i, 0], p[i, 1],
                           p[i, 2], n[i, 0], n[i, 1], n[i, 2])


def empty_tree():
    """(tree_f, tree_i, infinite, inf_f) of no selector: the kernels' arguments when
    every light is sampled."""
    return (np.zeros((0, NF)), np.zeros((0, NI), np.int64), np.zeros(0, np.int64),
            np.zeros((0, NINF)))


@register_warm_up
def _warm_up():
    from .point import PointLight
    lights = [PointLight(f"p{i}", pos=np.array([float(i), 0.0, 1.0]), radius=0.0,
                         intensity=np.ones(3), dir=np.array([0.0, 0.0, -1.0]))
              for i in range(3)]
    sel = LightSelector(lights, [0, 1, 2])
    p = np.zeros((1, 3))
    n = np.array([[0.0, 0.0, 1.0]])
    sel.select(p, n, np.full(1, 0.3))
    sel.pmf(p, n, 1)
    out = np.empty(1)
    pmf_each(p, n, np.zeros(1, np.int64), sel.tree_f, sel.tree_i, sel.leaf_of, out)


def selection_samples(settings) -> int:
    """Shadow rays per camera sample when the tree picks the lights: `light_samples`
    (1 with soft shadows off)."""
    return 1 if settings.soft_shadows == "off" else max(1, int(settings.light_samples))


def tree_members(lights, skip_mesh_lights: bool = False) -> list:
    """Indices of the lights shadow rays may see (their diffuse visibility), without the
    emissive meshes when skip_mesh_lights, if they are more than SAMPLE_ALL_UP_TO (the
    light tree picks among them); else [] (every light gets its own shadow rays)."""
    from ..geometry import SHADOW
    members = [li for li, light in enumerate(lights)
               if light.ray_kinds & SHADOW and light.shadow_sampled
               and not (skip_mesh_lights and light.kind == MESH)]
    return members if len(members) > SAMPLE_ALL_UP_TO else []


def selector_for(ctx, skip_mesh_lights: bool = False):
    """(LightSelector, the kernels' tree arrays (tree_f, tree_i, inf_idx, inf_f,
    l_trace)) for the shadow rays of a render context (engine/render.py Context), or None
    when every light gets its own shadow rays (at most SAMPLE_ALL_UP_TO lights).
    Members: the lights shadow rays may see (their diffuse visibility), without the
    emissive meshes when the caller gathers those itself. Built once per context."""
    key = bool(skip_mesh_lights)
    cache = ctx.light_selectors
    if key in cache:
        return cache[key]
    members = tree_members(ctx.lights, key)
    out = None
    if members:
        sel = LightSelector(ctx.lights, members)
        shadows = ctx.plan.shadows if ctx.plan is not None else {}
        trace = np.array([bool(shadows.get(light.name, True)) for light in ctx.lights],
                         np.bool_)
        out = (sel, (sel.tree_f, sel.tree_i, sel.infinite, sel.inf_f, trace))
    cache[key] = out
    return out

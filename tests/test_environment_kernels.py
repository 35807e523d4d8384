"""The environment map's sampling helpers made cheaper for issue 13 (docs/performance.md,
"envsample") compute exactly what their plain definitions do, bit for bit: the Repeat
wrap, the CDF interval search, and the texel density (texel_ratio, unrolled from a 3 x 3
loop). References are plain Python on float64 (IEEE doubles, as the kernels)."""
import numpy as np

from engine.lights.environment import _find_interval, _wrap, texel_ratio


def test_wrap_is_python_modulo():
    for n in (1, 2, 3, 7, 64):
        for i in range(-3 * n - 2, 3 * n + 3):
            assert _wrap(i, n) == i % n


def test_find_interval_is_the_largest_index_at_or_below():
    rng = np.random.default_rng(4)
    for n in range(1, 40):
        for t in range(20):
            # non-decreasing, with flat runs (empty bins) and repeated values
            c = np.concatenate([[0.0], np.cumsum(rng.random(n) * (rng.random(n) < 0.6))])
            c /= max(c[-1], 1e-300)
            c[-1] = 1.0
            if t % 3 == 0:
                c = np.round(c, 1)
            for x in list(rng.random(10)) + list(c) + [0.0, 1.0, -0.5, 1.5]:
                below = [i for i in range(n) if c[i] <= x]
                assert _find_interval(c, n, x) == (below[-1] if below else 0)


def _texel_ratio_reference(px, i, j, fx, fy):
    """environment.texel_ratio's definition: hats x luminance over the tents' mean,
    summed over rows then columns of the wrapped 3 x 3 neighbourhood."""
    H, W = px.shape[:2]
    hy = (max(0.5 - fy, 0.0), 1.0 - abs(fy - 0.5), max(fy - 0.5, 0.0))
    hx = (max(0.5 - fx, 0.0), 1.0 - abs(fx - 0.5), max(fx - 0.5, 0.0))
    c = (0.125, 0.75, 0.125)
    value = mean = 0.0
    for b in range(3):
        for a in range(3):
            t = px[(i + b - 1) % H, (j + a - 1) % W].astype(np.float64)
            lum = float(t[0]) * 0.2126 + float(t[1]) * 0.7152 + float(t[2]) * 0.0722
            value += hy[b] * hx[a] * lum
            mean += c[b] * c[a] * lum
    return value / mean if mean > 0 else 1.0


def test_texel_ratio_is_its_loop_bit_for_bit():
    rng = np.random.default_rng(9)
    for H, W in ((1, 1), (2, 3), (5, 8)):
        px = (rng.random((H, W, 3)) * 10.0 ** rng.uniform(-3, 3, (H, W, 1))).astype(np.float32)
        px[rng.random((H, W)) < 0.2] = 0.0
        for _ in range(200):
            i, j = int(rng.integers(0, H)), int(rng.integers(0, W))
            fx, fy = float(rng.random()), float(rng.random())
            assert texel_ratio(px, 1, i, j, fx, fy) == _texel_ratio_reference(px, i, j, fx, fy)

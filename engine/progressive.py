"""Progressive photon mapping: passes whose search radius shrinks, averaged, with budgets.

Every pass is an independent render with fresh photons (a new seed) and a few camera
samples per pixel. The photon search area shrinks pass by pass as in Knaus & Zwicker 2011
("Progressive photon mapping: a probabilistic approach"): r_i^2 ~ i^(alpha - 1) with
alpha = 2/3, the same schedule as SPPM (docs/design.md, Photon mapping model) but
memoryless: no per-pixel statistics, each pass stands alone, which fits the wavefront
passes we already have.
We shrink the area through the number of neighbours of the k-NN estimate,

    k_i = max(K_MIN, k_1 * i^(alpha - 1))

since the k-NN radius satisfies pi r^2 * density = k: the same r^2 ~ i^(alpha - 1) where
the photons are, adapted to the local density, and each pass costs no more than the one
before (a fixed radius turned out 2-10x slower on dense caustics). Photon noise and
radius bias both shrink as passes accumulate; the running average converges (down to
the K_MIN floor).

Brightness holds over the passes (Figure 6 box against Cycles at 4096 spp,
bench/bench_accuracy.py): 0.997-0.999 from pass 1 to 16, and FLIP keeps falling (0.075,
0.047, 0.039, 0.033 at 1, 4, 8, 16 passes). Before the gather-map estimates were made
unbiased (docs/estimator_bias.md), each one counted its own photon (+3 photons' worth of
the kernel). At k=64 that happened to cancel the corners' deficit; at the smaller k of
later passes it no longer did, and the image drifted 1.6 % bright over 16 passes.

Error estimate: passes alternate between two independent halves A and B; for the average
C = (A + B) / 2, E[(A - B)^2] = 4 Var(C), so relMSE(C) ~ mean((A - B)^2 / 4 / (S^2 + 0.01))
with S = C blurred over 5x5 pixels standing in for the unknown reference. It measures
variance only: the bias of the photon search area is not in it (it shrinks with the passes
too). tests/test_progressive.py checks it against the true error.
"""
from __future__ import annotations

import time
from dataclasses import dataclass, replace

import numpy as np

from .film import EFFECTS, Film
from .render import _check_region, prepare_context, render_pass
from .resources import check_resources
from .scene import Scene
from .settings import RenderSettings

ALPHA = 2.0 / 3.0
K_MIN = 8
DEFAULT_MAX_PASSES = 16


@dataclass
class Budget:
    """Stop after this many passes, this many seconds, or at this estimated relMSE;
    whichever comes first. With none given, DEFAULT_MAX_PASSES passes."""

    passes: int | None = None
    seconds: float | None = None
    target_error: float | None = None

    def __post_init__(self):
        if self.passes is not None and int(self.passes) < 1:
            raise ValueError(f"budget 'passes' must be >= 1, got {self.passes}")
        if self.seconds is not None and not float(self.seconds) > 0:
            raise ValueError(f"budget 'seconds' must be > 0, got {self.seconds}")
        if self.target_error is not None and not float(self.target_error) > 0:
            raise ValueError(f"budget 'target_error' must be > 0, got {self.target_error}")


def relmse(x: np.ndarray, ref: np.ndarray) -> float:
    """Mean over pixels and channels of (x - ref)^2 / (ref^2 + 0.01) (docs/design.md,
    Measuring accuracy)."""
    return float(np.mean((x - ref) ** 2 / (ref ** 2 + 0.01)))


def half_error(a: np.ndarray, b: np.ndarray) -> float:
    """Estimated relMSE of (a + b) / 2 from two independent half-images.

    Numerator: (a - b)^2 / 4, whose expectation is Var(c). Denominator: the reference is
    unknown and c^2 overestimates it by Var(c) (at a few samples per pixel that hid a
    factor 2-3 of the error), so use c blurred over 5x5 pixels, whose square carries only
    1/25 of the noise."""
    from scipy.ndimage import uniform_filter
    c = 0.5 * (a + b)
    smooth = uniform_filter(c, size=(5, 5, 1), mode="nearest")
    return float(np.mean((a - b) ** 2 / 4.0 / (smooth * smooth + 0.01)))


def render_progressive(scene: Scene, settings: RenderSettings | None = None,
                       budget: Budget | None = None, progress=None, should_cancel=None,
                       on_pass=None, region=None) -> Film:
    """Render passes until the budget is spent. on_pass(film, info) is called after every
    pass with the running average (info: pass, photons, elapsed, error_estimate)."""
    settings = settings or RenderSettings()
    budget = budget or Budget()
    max_passes = budget.passes or (None if (budget.seconds or budget.target_error) else DEFAULT_MAX_PASSES)
    t_start = time.perf_counter()
    scene.validate()
    region = _check_region(region, scene.width, scene.height)
    check_resources(scene, settings, region, progressive=True)
    ctx = prepare_context(scene, settings)
    w, h = region[2] - region[0], region[3] - region[1]
    sums = {name: np.zeros((h, w, 3)) for name in EFFECTS}
    halves = [np.zeros((h, w, 3)), np.zeros((h, w, 3))]
    counts = [0, 0]
    extra = {"alpha": np.zeros((h, w)), "holdout": np.zeros((h, w)), "normal": np.zeros((h, w, 3)), "photon_hits": np.zeros((h, w, 3))}
    depth = np.full((h, w), np.inf)
    log = []
    film = Film(w, h, show_photons=settings.show_photons)
    error = float("nan")
    cancelled = False
    photons_total = 0
    i = 0
    try:
        while True:
            i += 1
            k_i = max(K_MIN, int(round(settings.k_nearest * i ** (ALPHA - 1.0))))
            pass_settings = replace(settings, seed=settings.seed * 1_000_003 + i, k_nearest=k_i,
                                    min_photons=1)
            ctx.settings = pass_settings

            def pass_progress(stage, fraction, text, _i=i):
                if progress is not None:
                    progress(stage, fraction, f"Pass {_i}: {text}")

            t_pass = time.perf_counter()
            one = render_pass(ctx, region, pass_progress, should_cancel)
            if one.stats.get("cancelled"):
                cancelled = True
                i -= 1
                break
            photons_total += one.stats.get("photons_emitted", 0) + one.stats.get("caustic_photons_emitted", 0)
            combined = one.combined.astype(np.float64)
            for name in EFFECTS:
                sums[name] += getattr(one, name)
            halves[i % 2] += combined
            counts[i % 2] += 1
            for name in extra:
                extra[name] += getattr(one, name)
            depth = np.minimum(depth, one.depth)
            if counts[0] and counts[1]:
                error = half_error(halves[0] / counts[0], halves[1] / counts[1])
            elapsed = time.perf_counter() - t_start
            _fill(film, sums, extra, depth, i)
            info = dict(passes=i, photons=photons_total, elapsed=elapsed, error_estimate=error,
                        k_nearest=k_i, pass_seconds=time.perf_counter() - t_pass)
            log.append(info)
            if on_pass is not None:
                on_pass(film, info)
            # Budgets.
            if max_passes is not None and i >= max_passes:
                break
            if budget.target_error is not None and np.isfinite(error) and error <= budget.target_error:
                break
            if budget.seconds is not None:
                mean_pass = elapsed / i
                if elapsed + mean_pass > budget.seconds:  # the next pass would overrun
                    break
    finally:
        ctx.accel.close()
    film.stats.update(progressive=True, passes=i, error_estimate=error, photons_total=photons_total,
                      pass_log=log, cancelled=cancelled, effects=ctx.plan.report(),
                      time_total=time.perf_counter() - t_start)
    film.warnings = scene.all_warnings()
    return film


def _fill(film: Film, sums, extra, depth, n):
    for name, total in sums.items():
        getattr(film, name)[...] = (total / n).astype(np.float32)
    film.alpha[...] = extra["alpha"] / n
    film.holdout[...] = extra["holdout"] / n
    film.photon_hits[...] = np.clip(extra["photon_hits"] / n, 0, None)
    nrm = extra["normal"]
    film.normal[...] = nrm / np.maximum(np.linalg.norm(nrm, axis=2, keepdims=True), 1e-300)
    film.depth[...] = depth

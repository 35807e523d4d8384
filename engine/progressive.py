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

from .datapasses import FIRST_SAMPLE
from .effects import shot_words
from .film import EFFECTS, Film
from .lights import light_census
from .mallocheap import render_heap
from .parallel import Cancelled
from .render import (_check_region, close_context, prepare_context, render_cryptomatte,
                     render_pass, warning_teller)
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


def pass_settings(settings: RenderSettings, i: int) -> RenderSettings:
    """Settings of pass i (1-based): its own seed and its k_i = max(K_MIN, k_1 i^(alpha-1)).
    A pass depends on nothing else, so passes can run anywhere in any order
    (engine/distributed.py)."""
    k_i = max(K_MIN, int(round(settings.k_nearest * i ** (ALPHA - 1.0))))
    # Adaptive sampling (Noise Threshold) is the plain render's: a pass's few samples are
    # below its min samples, and its half-buffer estimate would not see the passes' photon
    # noise (ADAPTIVE_WARNING).
    return replace(settings, seed=settings.seed * 1_000_003 + i, k_nearest=k_i, min_photons=1,
                   adaptive_threshold=0.0)


ADAPTIVE_WARNING = ("Noise Threshold (adaptive sampling) applies to the plain render only: "
                    "progressive passes take all their samples")


def max_passes_of(budget: Budget) -> int | None:
    """The pass limit of a budget: its passes, else DEFAULT_MAX_PASSES when it has no
    time or error limit either, else None (no pass limit)."""
    return budget.passes or (None if (budget.seconds or budget.target_error) else DEFAULT_MAX_PASSES)


def overrun_warning(budget: Budget, settings: RenderSettings, pass_seconds: float) -> str | None:
    """The warning when pass 1 alone took longer than the budget's seconds (None when it
    did not, or there is no time limit). A pass is a whole render and cannot stop
    halfway, so a time limit shorter than one pass is overrun by that pass; the user's
    remedy is fewer samples or photons per pass."""
    if budget.seconds is None or not pass_seconds > budget.seconds:
        return None
    return (f"progressive: pass 1 took {pass_seconds:.1f} s, more than the "
            f"{budget.seconds:g} s time limit (a pass cannot stop halfway); lower the "
            f"samples per pass ({settings.spp}) or the photons per pass "
            f"({settings.photons:,}) so that several passes fit in the limit")


def budget_spent(budget: Budget, passes: int, error: float, elapsed: float) -> bool:
    """True when no further pass should start after `passes` merged passes with the
    running error estimate and elapsed seconds: the pass limit is reached, the error
    target is met, or the next pass (at the mean pass time so far) would overrun."""
    max_passes = max_passes_of(budget)
    if max_passes is not None and passes >= max_passes:
        return True
    if budget.target_error is not None and np.isfinite(error) and error <= budget.target_error:
        return True
    if budget.seconds is not None and elapsed + elapsed / passes > budget.seconds:
        return True
    return False


class PassMerger:
    """Running average of pass films, merged strictly in pass order.

    The float64 sums are formed in the same order whoever rendered the passes, so the
    average is bitwise the same on one machine and on a cluster (engine/distributed.py).
    self.film (one Film, updated in place) holds the average after every add()."""

    def __init__(self, width: int, height: int, show_photons: bool = False):
        w, h = width, height
        self.sums = {name: np.zeros((h, w, 3)) for name in EFFECTS}
        self.halves = [np.zeros((h, w, 3)), np.zeros((h, w, 3))]
        self.counts = [0, 0]
        self.extra = {"alpha": np.zeros((h, w)), "holdout": np.zeros((h, w)),
                      "normal": np.zeros((h, w, 3)), "photon_hits": np.zeros((h, w, 3))}
        self.depth = np.full((h, w), np.inf)
        self.data = {}
        self.catcher = {}
        self.film = Film(w, h, show_photons=show_photons)
        self.passes = 0
        self.photons = 0
        self.error = float("nan")

    def add(self, one: Film) -> None:
        """Merge pass self.passes + 1. A pass film rendered without photon view may carry
        photon_hits=None (all zero, not worth shipping): adding zeros changes nothing."""
        self.passes += 1
        i = self.passes
        st = one.stats  # every shot's photons, each once (render._photon_pass)
        self.photons += st.get("photons_emitted_all", st.get("photons_emitted", 0)
                               + st.get("caustic_photons_emitted", 0))
        # The render's sum (not the photon-hit view that combined is with show_photons).
        combined = sum(getattr(one, name) for name in EFFECTS).astype(np.float64)
        for name in EFFECTS:
            self.sums[name] += getattr(one, name)
        self.halves[i % 2] += combined
        self.counts[i % 2] += 1
        for name in self.extra:
            value = getattr(one, name)
            if value is not None:
                self.extra[name] += value
        if i == 1:  # Depth is the first sample's (Cycles' sample 0): the first pass holds it
            self.depth = np.array(one.depth, np.float64)
        # Cycles' data passes (engine/datapasses.py): averaged over the passes as the
        # effects are (each pass' film holds its per-sample averages); those written by
        # a pixel's first sample (FIRST_SAMPLE) kept from the first pass, as Cycles
        # keeps sample 0's.
        for key, value in getattr(one, "data", {}).items():
            if key in FIRST_SAMPLE:
                self.film.data.setdefault(key, value.copy())
                continue
            self.data[key] = self.data.get(key, 0.0) + value.astype(np.float64)
        if getattr(one, "cryptomatte", None) and not self.film.cryptomatte:
            # Cryptomatte: the first pass makes the mattes (engine/cryptomatte.py: exact
            # coverage counts of their own rays, not an average of passes).
            self.film.cryptomatte = one.cryptomatte
            self.film.cryptomatte_names = one.cryptomatte_names
        if getattr(one, "catcher", None) is not None:
            # Shadow catchers: their per-sample means averaged over the passes as the
            # effects are (engine/shadowcatcher.py forms the ratio from the averages).
            for key, value in one.catcher.items():
                self.catcher[key] = self.catcher.get(key, 0.0) + np.asarray(value, np.float64)
            self.film.catcher = {key: total / i for key, total in self.catcher.items()}
        if self.counts[0] and self.counts[1]:
            self.error = half_error(self.halves[0] / self.counts[0], self.halves[1] / self.counts[1])
        _fill(self.film, self.sums, self.extra, self.depth, i)
        for key, total in self.data.items():
            self.film.data[key] = (total / i).astype(np.float32)


def add_shot_counts(shots: dict, stats: dict) -> None:
    """Sum a pass' caustic shot counts (stats caustic_shot_stored, caustic_photons_emitted,
    caustic_shot_aimed: render._photon_pass) into shots, in place, for effects.shot_words
    over all the passes (the local and the Dask passes alike)."""
    for key in ("caustic_shot_stored", "caustic_photons_emitted"):
        if stats.get(key) is not None:
            shots[key] = shots.get(key, 0) + int(stats[key])
    shots["caustic_shot_aimed"] = bool(stats.get("caustic_shot_aimed"))


def render_progressive(scene: Scene, settings: RenderSettings | None = None,
                       budget: Budget | None = None, progress=None, should_cancel=None,
                       on_pass=None, region=None, on_warning=None) -> Film:
    """Render passes until the budget is spent. on_pass(film, info) is called after every
    pass with the running average (info: pass, photons, elapsed, error_estimate).
    on_warning(text): each of film.warnings once, when known (engine/render.py, render;
    the passes' search-radius warnings once in all, the first pass' words).
    engine/distributed.py renders the same passes on a Dask cluster (bitwise the same
    image)."""
    settings = settings or RenderSettings()
    budget = budget or Budget()
    t_start = time.perf_counter()
    scene.validate()
    region = _check_region(region, scene.width, scene.height)
    check_resources(scene, settings, region, progressive=True)
    tell = warning_teller(on_warning)
    tell(scene.all_warnings())
    w, h = region[2] - region[0], region[3] - region[1]
    merger = PassMerger(w, h, settings.show_photons)
    try:
        ctx = prepare_context(scene, settings, should_cancel=should_cancel)
    except Cancelled:  # before the first pass: an empty film, marked as cancelled
        film = merger.film
        film.stats.update(progressive=True, passes=0, photons_total=0, pass_log=[],
                          cancelled=True, time_total=time.perf_counter() - t_start)
        film.warnings = scene.all_warnings()
        tell(film.warnings)
        return film
    tell(scene.all_warnings() + ctx.plan.warnings)  # before the first pass
    if settings.light_groups:  # (their scenes built once, for every pass)
        ctx.light_group_contexts = {}
    # The passes' own warnings (a hand-set search radius: render.radius_warnings), told
    # as each pass' photon maps are built, before its camera pass; once each
    # (render.warning_key: every pass words the same advice with its own photon count).
    pass_warnings = []

    def tell_pass(text):
        pass_warnings.extend(tell([text]))

    if settings.adaptive_threshold > 0:
        tell_pass(ADAPTIVE_WARNING)

    log = []
    cancelled = False
    i = 0
    shots = {}  # the caustic shots' stored / emitted photons over the passes (shot_words)
    try:
        # One malloc setting over all the passes (engine/mallocheap.py): the heaps a
        # pass grew serve the next, trimmed once at the end, not after every pass.
        with render_heap():
            while True:
                i += 1
                ctx.settings = pass_settings(settings, i)

                def pass_progress(stage, fraction, text, _i=i):
                    if progress is not None:
                        progress(stage, fraction, f"Pass {_i}: {text}")

                t_pass = time.perf_counter()
                one = render_pass(ctx, region, pass_progress, should_cancel, on_warning=tell_pass)
                if i == 1 and settings.cryptomatte and not one.stats.get("cancelled"):
                    render_cryptomatte(ctx, region, one, should_cancel)  # pass 1's, kept
                if one.stats.get("cancelled"):
                    cancelled = True
                    i -= 1
                    break
                merger.add(one)
                add_shot_counts(shots, one.stats)
                elapsed = time.perf_counter() - t_start
                info = dict(passes=i, photons=merger.photons, elapsed=elapsed,
                            error_estimate=merger.error, k_nearest=ctx.settings.k_nearest,
                            pass_seconds=time.perf_counter() - t_pass)
                log.append(info)
                if i == 1 and (overrun := overrun_warning(budget, settings, info["pass_seconds"])):
                    tell_pass(overrun)
                if on_pass is not None:
                    on_pass(merger.film, info)
                if budget_spent(budget, i, merger.error, elapsed):
                    break
    finally:
        close_context(ctx)
    film = merger.film
    film.stats.update(progressive=True, passes=i, error_estimate=merger.error,
                      photons_total=merger.photons, pass_log=log, cancelled=cancelled,
                      effects=shot_words(ctx.plan.report(), shots),
                      light_census=light_census(ctx.lights, scene),
                      time_total=time.perf_counter() - t_start)
    film.warnings = scene.all_warnings() + ctx.plan.warnings + pass_warnings
    tell(film.warnings)
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

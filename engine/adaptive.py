"""Adaptive sampling as Cycles does it (Render Properties > Sampling > Noise Threshold).

A pixel stops taking camera samples once its noise estimate falls below the threshold.
What follows Cycles (blender/blender, read 2026-12):

- intern/cycles/scene/integrator.cpp, Integrator::get_adaptive_sampling: Min Samples 0
  (auto) = max(4, ceil(16 / threshold^0.3)) ("Threshold 0.1 -> 32, 0.01 -> 64"), a set
  value is at least 4; the threshold the check compares with is the user's times 5 ("an
  arbitrary factor that makes the threshold more similar to what it was before");
  adaptive_step = 16.
- intern/cycles/integrator/adaptive_sampling.cpp, need_filter / align_samples: the check
  runs after 0-based sample s when s > min_samples and s % 16 == 15; the samples before the
  first check are taken in one go, then 16 at a time (Schedule).
- intern/cycles/kernel/film/adaptive_sampling.h, film_adaptive_sampling_convergence_check:
  error = (|I.r - A.r| + |I.g - A.g| + |I.b - A.b|) / (0.0001 + sqrt(I.r + I.g + I.b))
  (the denominator is I.r + I.g + I.b itself once that is >= 1: "highly exposed"), I the
  pixel's mean over all its samples, A its mean over half of them (Dammertz et al. 2010,
  "A hierarchical automatic stopping condition for Monte Carlo global illumination",
  section 2.1); converged when error < threshold. Then film_adaptive_sampling_filter_x /
  _y: a pixel next to an unconverged one (3 x 3 box) keeps sampling, converged or not.

Where we differ, and why:

- The half A. Cycles' half is every other sample (sample_is_class_A). Our caustic and
  secondary-caustic estimates are taken at one sample in `stride` of a pixel
  (integrator._smooth_estimate) and weighted up: with stride even they would all fall in
  one half and the pixel would never converge. class_a() puts the samples in the halves by
  the parity of (round + sub + sum of sub // stride), which alternates the estimate-taking
  samples between the halves, and A is the mean over the samples of its half (their
  count per pixel is kept) rather than Cycles' 2 x sum / n.
- Stratification. Cycles' sample sequences (Sobol-Burley, PMJ) stay well stratified over
  any prefix; our StratifiedSampler stratifies over the samples it is told a pixel takes.
  Each round is stratified on its own: a round of R samples per pixel is an independent
  m x m grid (m = floor(sqrt(R))) with its own scramble (integrator._render_round).
- No exposure factor: the film is scene-linear; the add-on's view transform comes later.
"""
from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

STEP = 16  # Cycles' adaptive_step: samples between two convergence checks
THRESHOLD_SCALE = 5.0  # Cycles' "arbitrary factor" on the user's threshold
MIN_SAMPLES_FLOOR = 4  # Cycles: min samples are never fewer than 4


def auto_min_samples(threshold: float) -> int:
    """Cycles' automatic Min Samples for a Noise Threshold (> 0): max(4,
    ceil(16 / threshold^0.3)): 0.1 -> 32, 0.05 -> 40, 0.02 -> 52, 0.01 -> 64."""
    # float32 as Cycles computes it (ceilf(16.0f / powf(t, 0.3f))): 0.01 gives 64, not 65
    m = math.ceil(float(np.float32(16.0) / np.power(np.float32(threshold), np.float32(0.3))))
    return max(MIN_SAMPLES_FLOOR, m)


@dataclass(frozen=True)
class Schedule:
    """The camera pass's rounds under adaptive sampling.

    threshold: the user's Noise Threshold (> 0); min_samples: the user's Min Samples (0 =
    auto, auto_min_samples); spp: the most samples a pixel takes."""

    threshold: float
    min_samples: int
    spp: int

    @property
    def min_effective(self) -> int:
        """Samples every pixel takes: Cycles' min_samples (auto or at least 4), at most
        spp."""
        m = auto_min_samples(self.threshold) if self.min_samples == 0 else \
            max(MIN_SAMPLES_FLOOR, self.min_samples)
        return min(m, self.spp)

    @property
    def check_threshold(self) -> float:
        """The number the error is compared with: the user's threshold x 5 (Cycles)."""
        return self.threshold * THRESHOLD_SCALE

    def rounds(self) -> list[tuple[int, int, bool]]:
        """[(first sample, end sample, check after it)]: the samples [first, end) of a
        pixel that one round adds; check: a convergence check follows (Cycles'
        need_filter(end - 1)). The first round runs to Cycles' first filter sample
        ((min_samples + 1) | (STEP - 1), 0-based), the next ones STEP samples each, the last
        one ends at spp."""
        first_end = ((self.min_effective + 1) | (STEP - 1)) + 1
        out = []
        a = 0
        end = min(first_end, self.spp)
        while a < self.spp:
            out.append((a, end, end < self.spp and self.need_filter(end - 1)))
            a, end = end, min(end + STEP, self.spp)
        return out

    def need_filter(self, sample: int) -> bool:
        """Cycles' AdaptiveSampling::need_filter: after 0-based sample `sample`."""
        return sample > self.min_effective and (sample & (STEP - 1)) == STEP - 1


def schedule_warnings(threshold: float, min_samples: int, spp: int) -> list[str]:
    """[a warning] when a Noise Threshold (> 0) can stop no pixel early: the first
    convergence check comes after Min Samples (auto from the threshold) and a round of up to
    STEP samples, and Max Samples (spp) ends every pixel before it (a new-user trial: 32
    samples at threshold 0.05, auto minimum 40, rendered exactly as without it). []
    otherwise, or without a threshold."""
    if not threshold > 0:
        return []
    schedule = Schedule(threshold, min_samples, spp)
    if any(check for _, _, check in schedule.rounds()):
        return []
    first = ((schedule.min_effective + 1) | (STEP - 1)) + 1
    minimum = (f"Min Samples {max(MIN_SAMPLES_FLOOR, min_samples)}" if min_samples else
               f"Min Samples, automatic for this threshold: {auto_min_samples(threshold)}")
    return [f"Noise Threshold {threshold:g} has no effect at Max Samples {spp}: the noise "
            f"is first checked after sample {first} ({minimum}, rounded up to a multiple "
            f"of {STEP}, as Cycles does), so every pixel takes all {spp} samples. Raise Max "
            f"Samples above {first}" + (" or lower Min Samples" if first > STEP else "")]


def class_a(sub: np.ndarray, round_index: int, strides) -> np.ndarray:
    """(N,) bool: the samples sub (N,) int64 (a pixel's samples in its round, 0-based) of
    round round_index that go into half A. strides: the strides of the smooth estimates
    (integrator._smooth_estimate: one sample in stride takes one); the parity of
    round + sub + sum(sub // stride) alternates both every sample and every estimate-
    taking sample (sub % stride == 0) between the halves, and round by round the first
    sample of a round (which takes every estimate) too."""
    k = sub + round_index
    for s in strides:
        if s > 1:
            k = k + sub // s
    return (k & 1).astype(bool)


def pixel_error(full: np.ndarray, n: np.ndarray, half: np.ndarray, n_half: np.ndarray):
    """Cycles' per-pixel error (film_adaptive_sampling_convergence_check): full (P,3) sum
    of a pixel's samples' radiance, n (P,) their count, half (P,3) and n_half (P,) the
    same over half A. Returns (P,) float64; a pixel without samples in A: +inf."""
    with np.errstate(invalid="ignore", divide="ignore"):
        i_mean = full / n[:, None]
        a_mean = half / n_half[:, None]
    diff = np.abs(i_mean - a_mean).sum(axis=1)
    intensity = i_mean.sum(axis=1)
    normalize = np.where(intensity < 1.0, np.sqrt(np.maximum(intensity, 0.0)), intensity)
    err = diff / (0.0001 + normalize)
    return np.where(n_half > 0, err, np.inf)


def dilate_unconverged(converged: np.ndarray) -> np.ndarray:
    """Cycles' film_adaptive_sampling_filter_x then _y: a pixel stays active when it or a
    neighbour in x, then (of that result) in y, is unconverged (a 3 x 3 box dilation of
    the unconverged set). converged (H,W) bool -> (H,W) bool, a new array."""
    active = ~converged
    x = active.copy()
    x[:, 1:] |= active[:, :-1]
    x[:, :-1] |= active[:, 1:]
    y = x.copy()
    y[1:, :] |= x[:-1, :]
    y[:-1, :] |= x[1:, :]
    return ~y


def pixel_hash(pix: np.ndarray, round_index: int, seed: int) -> np.ndarray:
    """(N,) uint64 hash of region pixels pix (N,) int64, a round and the seed (a
    splitmix64 finaliser, as sampling._stratified_uv scrambles its cells): the shift of
    a pixel's jitter cells in an adaptive round (integrator._render_round_chunk)."""
    add = np.uint64(((round_index + 1) * 0xBF58476D1CE4E5B9 + int(seed) * 0xD6E8FEB86659FD93)
                    % (1 << 64))
    with np.errstate(over="ignore"):
        x = pix.astype(np.uint64) * np.uint64(0x9E3779B97F4A7C15) + add
        x ^= x >> np.uint64(31)
        x *= np.uint64(0x94D049BB133111EB)
        x ^= x >> np.uint64(29)
    return x

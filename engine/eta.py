"""Remaining time of a render for the progress bars of the CLI (engine/cli.py) and the
batch command (addon/batch.py).

A rate measured from the start of the run is wrong for most of a first render on a
machine: the kernel compile (minutes, engine/jit.py), loading the scene and the first
chunk of work (one-off set-up inside it) report no or little progress, so right after
them the estimate is many times the real remaining time and falls only slowly. Eta
measures the rate from a later point instead: the first progress reported after work
began (the first chunk finished), re-taken when a one-off stage starts again (restart()).

The bar's fraction weighs the stages by a guess of their cost (engine/stagespans.py: a
photon against a camera sample, 0.012-1.0 by scene): the rate of one stage tells nothing
of the next one's. The first make render (newuser37) promised 11:09 at 2 % for 51 s of
work: the rate was that of the set-up and the photon stages (0.15 %/s of the bar, where
the camera pass then moved it 2 %/s); an 11 s render showed 00:14 -> 00:09 -> 00:06
through its photon stages. So a caller that tells the stage of each report
(update(fraction, stage)) and the stage that ends the render (final_stage) gets an
estimate only inside that last stage (the camera pass: most of a render's time, 25 of
28 s for Figure 6), its rate measured from the stage's own first report: no estimate
rather than a guess before it. Without stages (progressive passes, each a photon and a
camera stage) the rate is that of a recent window: the last `window` share of the time
since the starting point (at least min_seconds), which follows the stage being run. The
window applies within the camera pass too: a machine that gets busier slows it.
"""
from __future__ import annotations

import math
import time


class Eta:
    """Remaining seconds of a run whose progress is a fraction 0..1.

    update(fraction, stage=None) after each progress report (a fraction below the last
    one is ignored: the bars never move back); restart() when a one-off stage begins (the
    next report becomes the new starting point); remaining() -> seconds or None. An
    estimate needs min_fraction of the work and min_seconds of time since the starting
    point; its rate is that of the last `window` share of that time. final_stage: the
    stage that ends the run ("render", the camera pass): reports that name a stage start
    the rate anew at each new stage, and there is no estimate before final_stage (module
    docstring). clock: seconds (time.monotonic; tests pass their own)."""

    def __init__(self, min_fraction: float = 0.01, min_seconds: float = 0.5,
                 window: float = 0.3, clock=None, final_stage: str | None = None):
        self.final_stage = final_stage
        self._stage = None  # the stage of the newest report (None: not told)
        self.min_fraction = float(min_fraction)
        self.min_seconds = float(min_seconds)
        self.window = float(window)
        self.clock = clock or time.monotonic
        self._start = None  # (time, fraction) the rate is measured from
        self._last = None   # (time, fraction) of the newest report
        self._history = []  # (time, fraction) reports since the start, for the window
        self._fraction = 0.0

    def restart(self) -> None:
        """Forget the starting point (a compile or another one-off stage begins)."""
        self._start = self._last = None
        self._history = []

    def update(self, fraction: float, stage: str | None = None) -> None:
        f = min(max(float(fraction), 0.0), 1.0) if math.isfinite(fraction) else 0.0
        if f < self._fraction:
            return
        now = self.clock()
        if stage is not None and stage != self._stage:
            # A new stage: its rate from its own first report (its set-up and first chunk
            # done), not through the last stage's.
            self._stage = stage
            self._start = (now, f)
            self._last = None
            self._history = [self._start]
        elif self._start is None:
            # Work reported before the first chunk ends includes its set-up: the rate
            # counts from the first report that shows progress.
            if f > self._fraction or f >= 1.0:
                self._start = (now, f)
                self._history = [self._start]
        else:
            self._last = (now, f)
            self._history.append(self._last)
            # Keep one report at or before the oldest window that can still be asked for.
            cut = now - max(self.min_seconds, self.window * (now - self._start[0]))
            while len(self._history) > 2 and self._history[1][0] <= cut:
                self._history.pop(0)
        self._fraction = f

    def remaining(self) -> float | None:
        """Seconds left at the rate of the recent window, counted down from the newest
        report; None until enough work has been seen."""
        if self._fraction >= 1.0:
            return 0.0
        if self._start is None or self._last is None:
            return None
        if (self.final_stage is not None and self._stage is not None
                and self._stage != self.final_stage):
            return None  # a stage before the last: its rate says nothing of the rest
        (ts, fs), (t1, f1) = self._start, self._last
        if f1 - fs < self.min_fraction or t1 - ts < self.min_seconds:
            return None
        # The newest report at least the window before the last one (the start if none).
        cut = t1 - max(self.min_seconds, self.window * (t1 - ts))
        t0, f0 = self._history[0]
        for t, f in self._history:
            if t > cut:
                break
            t0, f0 = t, f
        if f1 <= f0:
            return None
        rate = (f1 - f0) / (t1 - t0)
        return max(0.0, (1.0 - f1) / rate - (self.clock() - t1))

    def text(self) -> str:
        """remaining() as [h:]mm:ss, or '?' without an estimate."""
        return format_seconds(self.remaining())


def format_seconds(seconds: float | None) -> str:
    """[h:]mm:ss as tqdm shows times, or '?' for None."""
    if seconds is None:
        return "?"
    s = int(round(seconds))
    h, rest = divmod(s, 3600)
    m, s = divmod(rest, 60)
    return f"{h:d}:{m:02d}:{s:02d}" if h else f"{m:02d}:{s:02d}"


def progress_bar(desc: str, bar_format: str, stream, eta: Eta):
    """A tqdm bar of 1000 steps whose bar_format may show `{eta}`: eta.text() (tqdm's own
    {remaining} measures the rate from the bar's start, compile included)."""
    from tqdm import tqdm

    class _Bar(tqdm):
        @property
        def format_dict(self):
            d = super().format_dict
            d["eta"] = eta.text()
            return d

    return _Bar(total=1000, desc=desc, file=stream, unit="", bar_format=bar_format)

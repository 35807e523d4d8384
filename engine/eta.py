"""Remaining time of a render for the progress bars of the CLI (engine/cli.py) and the
batch command (addon/batch.py).

A rate measured from the start of the run is wrong for most of a first render on a
machine: the kernel compile (about a minute, engine/jit.py), loading the scene and the
first chunk of work (one-off set-up inside it) report no or little progress, so right
after them the estimate is many times the real remaining time and falls only slowly.
Eta measures the rate from a later point instead: the first progress reported after work
began (the first chunk finished), re-taken when a one-off stage starts again (restart()).
Before enough work has been seen since that point it gives no estimate rather than a
guess.
"""
from __future__ import annotations

import math
import time


class Eta:
    """Remaining seconds of a run whose progress is a fraction 0..1.

    update(fraction) after each progress report (a fraction below the last one is
    ignored: the bars never move back); restart() when a one-off stage begins (the next
    report becomes the new starting point); remaining() -> seconds or None. An estimate
    needs min_fraction of the work and min_seconds of time since the starting point.
    clock: seconds (time.monotonic; tests pass their own)."""

    def __init__(self, min_fraction: float = 0.01, min_seconds: float = 0.5, clock=None):
        self.min_fraction = float(min_fraction)
        self.min_seconds = float(min_seconds)
        self.clock = clock or time.monotonic
        self._start = None  # (time, fraction) the rate is measured from
        self._last = None   # (time, fraction) of the newest report
        self._fraction = 0.0

    def restart(self) -> None:
        """Forget the starting point (a compile or another one-off stage begins)."""
        self._start = self._last = None

    def update(self, fraction: float) -> None:
        f = min(max(float(fraction), 0.0), 1.0) if math.isfinite(fraction) else 0.0
        if f < self._fraction:
            return
        now = self.clock()
        if self._start is None:
            # Work reported before the first chunk ends includes its set-up: the rate
            # counts from the first report that shows progress.
            if f > self._fraction or f >= 1.0:
                self._start = (now, f)
        else:
            self._last = (now, f)
        self._fraction = f

    def remaining(self) -> float | None:
        """Seconds left at the rate since the starting point, counted down from the
        newest report; None until enough work has been seen."""
        if self._fraction >= 1.0:
            return 0.0
        if self._start is None or self._last is None:
            return None
        (t0, f0), (t1, f1) = self._start, self._last
        if f1 - f0 < self.min_fraction or t1 - t0 < self.min_seconds:
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

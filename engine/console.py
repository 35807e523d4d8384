"""A command's progress bar and the lines printed beside it: one writer for both front
ends, the engine's CLI (engine/cli.py) and the Blender batch command (addon/batch.py).

A line printed while a tqdm bar is shown (a scene's warning, a pass's summary, a Python
warning from numpy, scipy, numba or our code) must start a line of its own and leave the
bar's text whole, also where stdout and stderr are one file (`cmd > log 2>&1`, a CI
log): there a cleared line stays in the text, so the bar's line is ended with a newline
first (new-user trials, s17 and s19). Every write goes through one lock, so the engine's
worker threads (engine/parallel.py), whose Python warnings come here too, never print
into the middle of the bar or of another line.

In a file or a pipe every frame the bar draws stays in the text, so there each frame is a
line of its own (tqdm's "\r" before a frame starts no line in a log viewer: a render's
frames were one line of thousands of characters, s36), and a frame is drawn only when the
stage changes (its text, counts aside; the stage's last state first, when it was not
drawn), every LOG_FRAME_SECONDS otherwise, and at the close; never twice with the same
text, its clock aside (a stage's text and then its first progress step drew one state
twice, and closing the bar drew its last state again, below the lines printed after it:
"Cancelled" twice in a log, s30), unless LOG_IDLE_SECONDS passed without a new one: then
the same text with its clock, so a log shows the run alive."""
from __future__ import annotations

import re
import sys
import threading
import time
import warnings
from contextlib import contextmanager


def short_count(n: int) -> str:
    """A count for a progress line: 950 -> '950', 19200 -> '19k' (photons, pixels)."""
    return f"{n / 1000:.0f}k" if n >= 1000 else str(n)


# The bar's clock at the end of its frame ("[00:05<00:06]", the elapsed time and the ETA).
_CLOCK = re.compile(r"\s*\[[^\[\]]*\]\s*$")
# In a file or a pipe, a frame of the same stage at most this often (seconds): a minute's
# render logs a handful of lines, not one per chunk.
LOG_FRAME_SECONDS = 10.0
# ... and a frame that says what the last one said, after this long: its clock shows the
# run is alive through a step that reports nothing for minutes (a slow estimator chunk:
# 4.5 silent minutes in a teacher's log, newuser42). Needs the bar redrawn meanwhile
# (keep_alive, on through a whole render).
LOG_IDLE_SECONDS = 60.0


def isatty(stream) -> bool:
    """True for a terminal; False for a file, a pipe or a stream without isatty."""
    try:
        return bool(stream.isatty())
    except (AttributeError, ValueError, OSError):
        return False


class BarConsole:
    """The progress bar (a tqdm bar on `stream`, or None: quiet) and the lines printed
    beside it. Draw the bar only inside `with console.drawing() as bar:` and print
    other lines only with write_line (or print_warnings' Python warnings), all from any
    thread: the console's lock orders them."""

    def __init__(self, stream=None, bar=None):
        self.stream = stream or sys.stderr
        self.lock = threading.RLock()
        # What a bar draws into: the stream on a terminal, else one frame a line.
        self.bar_file = self.stream if isatty(self.stream) else _LogLines(self.stream)
        self.bar = bar
        self._python_seen = set()

    @property
    def bar(self):
        return self._bar

    @bar.setter
    def bar(self, bar):
        with self.lock:
            self._bar = bar
            self._drawn = bar is not None  # tqdm draws a bar when it is made
            self._last_frame = None
            self._closing = False
            if bar is not None and not isatty(self.stream):
                if getattr(bar.fp, "_wrapped", bar.fp) is not self.bar_file:
                    # Made on the stream itself: its frames go through bar_file from now
                    # on (tqdm prints through sp, made from the file at __init__).
                    self.bar_file.open = True  # the frame tqdm drew when it was made
                    bar.fp, bar.sp = self.bar_file, bar.status_printer(self.bar_file)
                # Whole blocks only: tqdm's partial blocks read as stray digits in a
                # file ("2 |", "#3 |", newuser37).
                bar.ascii = " #"
                self._last_frame = _frame_state(bar)
                self._last_stage = _stage(bar)
                self._last_time = time.monotonic()
                self._skipped = None  # the last frame not drawn, to end its stage with
                self._draw_changes_only(bar)

    def _draw_changes_only(self, bar) -> None:
        """Make `bar` (drawing into a file or a pipe) draw a frame only at a new stage,
        every LOG_FRAME_SECONDS and at the close, and never one that says what the frame
        last drawn said, its clock aside (module docstring)."""
        draw = bar.display

        def display(msg=None, pos=None):
            # Not under self.lock: tqdm's monitor thread draws holding tqdm's lock, which
            # the drawing() block takes after self.lock (the other order: a deadlock).
            # tqdm's own lock orders its draws.
            if msg is not None:  # (a clear, never used in a file: passed on)
                return draw(msg, pos)
            state, stage, now = _frame_state(bar), _stage(bar), time.monotonic()
            idle = (state == self._last_frame and not self._closing
                    and now - self._last_time >= LOG_IDLE_SECONDS)
            if not idle and (state == self._last_frame or (
                    stage == self._last_stage and not self._closing
                    and now - self._last_time < LOG_FRAME_SECONDS)):
                if state != self._last_frame:
                    self._skipped = str(bar)
                return True
            if self._skipped is not None and stage != self._last_stage:
                # A stage ends on its last state ("Tracing photons 400k/400k"), not on
                # the first one drawn (it read as if the count never got there).
                self.bar_file.write("\r" + self._skipped)
            self._skipped = None
            self._last_frame, self._last_stage, self._last_time = state, stage, now
            return draw(msg, pos)

        bar.display = display  # (tqdm draws through self.display: refresh, update, close)

    @contextmanager
    def drawing(self):
        """The bar to update (None when there is none), under the lock; whatever it
        draws is then on the stream's last line, to be ended before another line."""
        with self.lock:
            yield self._bar
            if self._bar is not None:
                self._drawn = True

    def write_line(self, line: str, out=None, end: str = "\n") -> None:
        """Print `line` + `end` to `out` (default: sys.stdout at the time) on a line of its
        own, the bar continuing below it: on a terminal the bar's line is cleared first
        and the bar redrawn after (tqdm.write's way); in a file or a pipe, where a
        cleared line stays in the text, the bar's line is ended with a newline first and
        the bar redraws below at its next update."""
        out = out or sys.stdout
        with self.lock:
            bar = self._bar
            tty = isatty(self.stream)
            if bar is not None and self._drawn:
                if tty:
                    bar.clear()
                else:
                    self.bar_file.end_line()
                self.stream.flush()
                self._drawn = False
            out.write(line + end)
            out.flush()
            if bar is not None and tty:
                bar.refresh()
                self._drawn = True

    def keep_alive(self, on: bool, interval: float = 1.0) -> None:
        """While on, a daemon thread redraws the bar every `interval` seconds, so its
        clock moves through a long step that reports nothing (the kernel compile: one
        module can take minutes on a busy machine; a slow estimator chunk). In a file the
        redraws draw a frame only as the rules above allow. Idempotent; close() stops it."""
        with self.lock:
            ticker = getattr(self, "_ticker", None)
            if on and ticker is None:
                stop = threading.Event()

                def tick():
                    while not stop.wait(interval):
                        with self.drawing() as bar:
                            if bar is not None:
                                bar.refresh()
                thread = threading.Thread(target=tick, daemon=True, name="bar keep-alive")
                self._ticker = (stop, thread)
                thread.start()
            elif not on and ticker is not None:
                self._ticker = None
                ticker[0].set()

    def close(self) -> None:
        """Close the bar (tqdm ends its line); later lines print as usual."""
        self.keep_alive(False)
        with self.lock:
            bar = self._bar
            if bar is not None:
                self._closing = True  # the last state is drawn, whatever its stage
                if (not self._drawn and not isatty(self.stream)
                        and _frame_state(bar) == self._last_frame):
                    # Its last state is on a line above the lines printed since: tqdm's
                    # closing frame and newline would repeat it below them.
                    bar.fp = _Discard()
                bar.close()
            self.bar = None

    def show_python_warning(self, message, category, filename, lineno, file=None,
                            line=None) -> None:
        """warnings.showwarning's signature: the warning as Python formats it, through
        write_line to `file` (default: sys.stderr at the time, Python's own place). One
        print per message, category and place for this console: two worker threads
        racing through the filter's registry with the same warning print it once."""
        key = (category, str(message), filename, lineno)
        with self.lock:
            if key in self._python_seen:
                return
            self._python_seen.add(key)
            text = warnings.formatwarning(message, category, filename, lineno, line)
            self.write_line(text.rstrip("\n"), file or sys.stderr)

    @contextmanager
    def python_warnings(self):
        """Route Python's warnings (warnings.warn, numpy's RuntimeWarning ...) through
        show_python_warning while the block runs, on every thread: worker threads look
        warnings.showwarning up when they warn. The filters are Python's (the default
        one prints a warning once per place). Enter it once, on the main thread, around
        the whole render: warnings.catch_warnings swaps module globals, so entering it
        on a worker thread, or per chunk, would race (Python's documentation)."""
        if threading.current_thread() is not threading.main_thread():
            yield  # nothing swapped: another thread's render must not race the main one
            return
        with warnings.catch_warnings():
            warnings.showwarning = self.show_python_warning
            yield


def _frame_state(bar) -> str:
    """What a bar's frame says, its clock aside (what a file needs to be shown again)."""
    return _CLOCK.sub("", str(bar)).rstrip()


def _stage(bar) -> str:
    """A bar's text without its counts: 'Tracing photons 100k/400k' -> 'Tracing photons
    k/k' (one stage however far it got)."""
    return re.sub(r"[0-9.,]+", "", bar.desc)


class _LogLines:
    """What a bar draws into in a file or a pipe: tqdm's frames ("\\r" + frame +
    padding) each on a line of its own, its closing newline passed on."""

    def __init__(self, stream):
        self.stream = stream
        self.open = False  # a frame is the stream's last text, its line not ended

    def write(self, text):
        if text.startswith("\r"):
            frame = text.lstrip("\r").rstrip(" ")
            if frame:  # (a clear writes blanks only: nothing to keep in a file)
                self.stream.write(("\n" if self.open else "") + frame)
                self.open = True
        elif text:
            self.stream.write(text)
            self.open = self.open and not text.endswith("\n")
        return len(text)

    def end_line(self) -> None:
        """End the last frame's line (a line is printed below it)."""
        if self.open:
            self.stream.write("\n")
            self.open = False

    def flush(self):
        self.stream.flush()


class _Discard:
    """A stream that keeps nothing (a closing bar's repeat of its last frame)."""

    def write(self, text):
        return len(text)

    def flush(self):
        pass

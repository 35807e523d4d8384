"""engine/console.py alone: lines and Python warnings from several threads beside a bar
drawn on the main thread, all into one file (stdout and stderr shared), each whole on a
line of its own; Python's showwarning comes back after the render."""
import io
import re
import sys
import threading
import warnings

from tqdm import tqdm

from engine.console import BarConsole

BAR = re.compile(r"^step \d+ +\|[^|]*\| *\d+/1000$")


def _warn_once_here():
    warnings.warn("raised on a worker thread", RuntimeWarning)  # one place: printed once


def test_lines_and_python_warnings_from_threads_stay_whole(monkeypatch):
    shared = io.StringIO()  # a file: no terminal, the bar's line is ended, not cleared
    monkeypatch.setattr(sys, "stderr", shared)  # Python's warnings' place: the same file
    before = warnings.showwarning
    console = BarConsole(shared)
    console.bar = tqdm(total=1000, file=shared, desc="step 0", bar_format="{desc:<12}|{bar}| "
                       "{n}/{total}", mininterval=0, miniters=1, ncols=60)
    start = threading.Barrier(5)

    def worker(k):
        start.wait()
        for i in range(40):
            console.write_line(f"thread {k} line {i}", shared)
            _warn_once_here()

    with console.python_warnings():
        threads = [threading.Thread(target=worker, args=(k,)) for k in range(4)]
        for t in threads:
            t.start()
        start.wait()
        for n in range(1, 201):
            with console.drawing() as bar:
                bar.set_description_str(f"step {n}", refresh=False)
                bar.n = 5 * n
                bar.refresh()
        for t in threads:
            t.join()
        console.close()
    assert warnings.showwarning is before  # the one before the render again
    text = shared.getvalue()
    segments = [seg for line in text.split("\n") for seg in line.split("\r") if seg]
    said = [seg for seg in segments if seg.startswith("thread ")]
    assert sorted(said) == sorted(f"thread {k} line {i}" for k in range(4) for i in range(40))
    assert text.count("RuntimeWarning: raised on a worker thread") == 1, text
    for seg in segments:  # everything else: a whole bar, or the warning's two lines
        assert (seg in said or BAR.match(seg) or "RuntimeWarning: raised on a worker" in seg
                or seg.strip().startswith("warnings.warn(")), repr(seg)
    for line in text.split("\n"):  # a line never mixes a bar drawing with a message
        assert not ("|" in line and ("thread " in line or "Warning" in line)), repr(line)


def test_a_bar_in_a_log_file_draws_a_line_per_stage_and_per_interval(monkeypatch):
    """In a file tqdm's "\\r" starts no line: a render's frames were one line of thousands
    of characters (s36). Each frame is a line of its own, drawn at a new stage (after the
    last state of the one before, when that was not drawn), every LOG_FRAME_SECONDS
    within one, and at the close; a line printed between two frames starts a line of its
    own too; the bar is whole blocks ('#'), no partial-block digits (newuser37)."""
    from engine import console as console_module
    clock = [100.0]
    monkeypatch.setattr(console_module.time, "monotonic", lambda: clock[0])
    shared = io.StringIO()
    console = BarConsole(shared)
    console.bar = tqdm(total=1000, file=console.bar_file, desc="Tracing photons 0k/400k",
                       bar_format="{desc:<26}|{bar}| {n}/{total}", mininterval=0,
                       miniters=1, ncols=60)
    for k in range(1, 44):  # 43 chunks, one a second: a line every 10 s of them
        clock[0] += 1.0
        with console.drawing() as bar:
            bar.set_description_str(f"Tracing photons {10 * k}k/400k", refresh=False)
            bar.n = 10 * k
            bar.refresh()
        if k == 25:
            console.write_line("Warning: a scene warning", shared)
    with console.drawing() as bar:
        bar.set_description_str("Rendering pixels 1k/12k", refresh=False)
        bar.n = 500
        bar.refresh()
    clock[0] += 1.0
    with console.drawing() as bar:
        bar.n = 600  # same stage, a second later: not drawn until the close
        bar.refresh()
    console.close()
    text = shared.getvalue()
    assert "\r" not in text and text.endswith("\n"), repr(text)
    lines = text.rstrip("\n").split("\n")
    tracing = [line for line in lines if line.startswith("Tracing photons")]
    # The first frame (0k), then one per 10 s: 10k..400k at seconds 101..140.
    # ... and the stage's last state (430k, not drawn in its last 3 s) before the next.
    assert [line.split()[2] for line in tracing] == ["0k/400k", "100k/400k", "200k/400k",
                                                     "300k/400k", "400k/400k",
                                                     "430k/400k"], lines
    assert "1" not in "".join(line.split("|")[1] for line in lines if "|" in line)
    assert "Warning: a scene warning" in lines
    assert [line.split("|")[-1].strip() for line in lines
            if line.startswith("Rendering")] == ["500/1000", "600/1000"], lines
    for line in lines:  # a whole bar or the warning, nothing glued together
        assert line == "Warning: a scene warning" or re.match(
            r"^(Tracing photons|Rendering pixels) [0-9k/]+ +\|[ #]*\| *\d+/1000$", line), line


def test_a_bar_in_a_log_file_shows_it_is_alive_through_a_silent_step(monkeypatch):
    """A step that reports nothing for minutes (a slow estimator chunk: 4.5 silent
    minutes in a teacher's log, newuser42) still draws its unchanged frame every
    LOG_IDLE_SECONDS, its clock moved, when the keep-alive ticker redraws the bar; the
    close does not repeat it."""
    from engine import console as console_module
    clock = [100.0]
    monkeypatch.setattr(console_module.time, "monotonic", lambda: clock[0])
    shared = io.StringIO()
    console = BarConsole(shared)
    console.bar = tqdm(total=1000, file=console.bar_file, desc="Estimating caustics",
                       bar_format="{desc:<26}| {n}/{total} [{postfix}]", postfix="  0 s",
                       mininterval=0, miniters=1)
    for second in range(1, 151):  # the ticker's redraws, one a second, no progress
        clock[0] += 1.0
        with console.drawing() as bar:
            bar.set_postfix_str(f"{second:3d} s", refresh=False)
            bar.refresh()
    console.close()
    lines = [line for line in shared.getvalue().split("\n") if line]
    # the first frame, then one at 60 and one at 120 s: the text, then the clock moved
    assert [line.split("[")[-1].lstrip(", ") for line in lines] == ["0 s]", "60 s]",
                                                                   "120 s]"], lines
    assert len({line.split("[")[0] for line in lines}) == 1, lines
    assert console_module.LOG_IDLE_SECONDS == 60.0

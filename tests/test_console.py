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

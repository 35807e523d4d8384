"""Run a command in a subprocess and wait until its stderr shows a pattern (progress
bars write '\r'-separated updates, so stderr is read in raw chunks, not lines)."""
import os
import re
import subprocess
import threading
import time


class Watched:
    def __init__(self, cmd, cwd, **kwargs):
        self.proc = subprocess.Popen(cmd, cwd=cwd, stdout=subprocess.DEVNULL,
                                     stderr=subprocess.PIPE, **kwargs)
        self._chunks = []
        self._reader = threading.Thread(target=self._read, daemon=True)
        self._reader.start()

    def _read(self):
        fd = self.proc.stderr.fileno()
        while True:
            data = os.read(fd, 4096)
            if not data:
                break
            self._chunks.append(data)

    @property
    def stderr(self) -> str:
        return b"".join(self._chunks).decode("utf-8", "replace")

    def wait_for(self, pattern, timeout=120.0) -> bool:
        """True once stderr matches `pattern`; False if the process ended or timed out."""
        rx = re.compile(pattern)
        end = time.monotonic() + timeout
        while time.monotonic() < end:
            if rx.search(self.stderr):
                return True
            if self.proc.poll() is not None:
                return bool(rx.search(self.stderr))
            time.sleep(0.05)
        return False

    def __enter__(self):
        return self

    def __exit__(self, *exc):
        if self.proc.poll() is None:  # a failed assertion must not leave it running
            self.proc.kill()
            self.proc.wait()
        return False

    def finish(self, timeout=120.0) -> int:
        try:
            rc = self.proc.wait(timeout)
        except subprocess.TimeoutExpired:
            self.proc.kill()
            self.proc.wait()
            raise
        self._reader.join(5)
        return rc

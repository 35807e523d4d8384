"""Memory of the running process (Linux /proc), for the bench scripts' child processes
(bench_memory.py, bench_instancing.py): they put this folder on sys.path (BENCH) and
import rss / hwm, also when they measure another checkout (--root)."""
import os

BENCH = os.path.dirname(os.path.abspath(__file__))


def rss() -> int:
    """Resident set size now, bytes."""
    with open("/proc/self/statm") as f:
        return int(f.read().split()[1]) * 4096


def hwm() -> int:
    """Peak resident set size (VmHWM) of this address space, bytes; reset by writing 5 to
    /proc/self/clear_refs."""
    with open("/proc/self/status") as f:
        for line in f:
            if line.startswith("VmHWM:"):
                return int(line.split()[1]) * 1024
    raise OSError("no VmHWM in /proc/self/status")

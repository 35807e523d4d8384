"""CPU seconds per test, for finding the default run's heavy tests on a busy machine
(docs/stability.md, "Test suite time (s42)"): wall times there are several times the
work, CPU seconds are not. Opt-in pytest plugin:

    PYTHONPATH=$PWD:$PWD/tests .venv/bin/python -m pytest -q tests -p cputime_plugin
    .venv/bin/python tests/cputime_plugin.py cputime.tsv    # sums by file

Each test's line in $CPUTIME_OUT (default cputime.tsv): node id, wall s, CPU s (this
process' threads and its reaped children: Blender, CLI and compile-helper processes), the
1-minute load average. Dask worker processes are reaped when their cluster closes: their
CPU lands on the test that closes it."""
import collections
import os
import sys
import time

import pytest

_out = None


def _cpu():
    t = os.times()
    return t.user + t.system + t.children_user + t.children_system


@pytest.hookimpl(hookwrapper=True)
def pytest_runtest_protocol(item, nextitem):
    global _out
    if _out is None:
        _out = open(os.environ.get("CPUTIME_OUT", "cputime.tsv"), "w", buffering=1)
    w0, c0 = time.time(), _cpu()
    yield
    _out.write(f"{item.nodeid}\t{time.time() - w0:.3f}\t{_cpu() - c0:.3f}\t"
               f"{os.getloadavg()[0]:.2f}\n")


def by_file(paths):
    """{test file: [wall s, CPU s, tests]} summed over the TSV files, heaviest first."""
    tot = collections.defaultdict(lambda: [0.0, 0.0, 0])
    for path in paths:
        with open(path) as f:
            for line in f:
                nodeid, wall, cpu, _ = line.rstrip("\n").split("\t")
                row = tot[nodeid.split("::")[0]]
                row[0] += float(wall)
                row[1] += float(cpu)
                row[2] += 1
    return dict(sorted(tot.items(), key=lambda kv: -kv[1][1]))


if __name__ == "__main__":
    rows = by_file(sys.argv[1:])
    wall, cpu, n = (sum(r[i] for r in rows.values()) for i in range(3))
    print(f"{n} tests, wall {wall:.0f} s, CPU {cpu:.0f} s")
    for name, (wall, cpu, n) in list(rows.items())[:40]:
        print(f"{cpu:8.1f} CPU s {wall:8.1f} wall s {n:5d}  {name}")

"""The corners of issue 14's closure sweep (roughness 0-1, metallic 0/1, IOR 1.1-2.4, views
0-85 degrees) that tests/test_closures_cycles.py leaves out: closure_cases.sweep_cases()
against the Cycles means in tests/references/closures_sweep.json (made by
`tools/make_closure_references.py --sweep`), with the renders and the 2 % check of
test_closures_cycles (imported, not copied). Results: docs/accuracy.md, Closure sweep."""
import json
import os

import pytest

import closure_cases as cc
import test_closures_cycles as tcc

REF = os.path.join(os.path.dirname(__file__), "references", "closures_sweep.json")
with open(REF) as f:
    SWEEP_REFS = json.load(f)

PLANES, FURNACES = cc.sweep_cases()

# Rough glass of IOR 2.4 traps light by total internal reflection; its furnace estimate is
# heavy-tailed on both sides: at r 1 and 64 spp ours has a standard error of 0.067 (6.7 %)
# over the ball's pixels, Cycles at 1024 samples 0.016. So these cases are rendered at
# 16384 spp (se 0.005, ~16 s of CPU each: slow) against 16384-sample Cycles references.
FURNACE_SPP = {"furnace_glass_ior2.4_r1.0": 16384, "furnace_glass_ior2.4_r0.8": 16384}
# Strict xfails for reported misses (none now). Glass IOR 2.4 r 0.8 was one (ours 0.9887 /
# 1.0001 against Cycles' 0.9586) until the glass albedo tables were made as Cycles' are
# (docs/design.md, Glass albedo tables): 0.9616 / 0.9566 (seeds 5 / 11).
MISSES = {}


def _check(monkeypatch, name, got):
    # test_closures_cycles._check reads its references from tcc.REFS: lend it this case's.
    monkeypatch.setitem(tcc.REFS, name, SWEEP_REFS[name])
    tcc._check(name, got)


def test_every_sweep_case_has_a_reference():
    assert set(PLANES) | set(FURNACES) == set(SWEEP_REFS) - {"_meta"}
    assert set(FURNACE_SPP) <= set(FURNACES)


@pytest.mark.parametrize("name", sorted(PLANES))
def test_sweep_plane_matches_cycles(monkeypatch, name):
    spec, view = PLANES[name]
    _check(monkeypatch, name, tcc.render_plane(spec, view))


def _marks(name):
    marks = [pytest.mark.slow] if name in FURNACE_SPP else []
    if name in MISSES:
        marks.append(pytest.mark.xfail(strict=True, reason=MISSES[name]))
    return pytest.param(name, marks=marks)


@pytest.mark.parametrize("name", [_marks(n) for n in sorted(FURNACES)])
def test_sweep_furnace_matches_cycles(monkeypatch, name):
    _check(monkeypatch, name, tcc.render_furnace(FURNACES[name],
                                                 spp=FURNACE_SPP.get(name, 64)))

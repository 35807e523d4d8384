"""Test set-up shared by every test.

pytest runs with --import-mode=importlib (pyproject.toml): the repository root holds the
extension's __init__.py, and pytest's default mode would import the root as a package
named after the checkout folder and put that folder's parent on sys.path, where any
sibling folder (another checkout named 'distributed', say) shadows a real package. So
sys.path gets exactly the repository root (engine/, addon/) and this folder (helpers)."""
import os
import sys

TESTS = os.path.dirname(os.path.abspath(__file__))
ROOT = os.path.dirname(TESTS)
for path in (TESTS, ROOT):
    if path not in sys.path:
        sys.path.insert(0, path)


import pytest  # noqa: E402  (after sys.path is set: the fixtures below import the engine)


@pytest.fixture
def continuation_only(monkeypatch):
    """Camera paths without light sampling for lights with a size: every lobe (and the
    refraction through rough glass) reaches them only by its sampled continuation, the
    estimate MIS must match on average. Patches the module function the render reads
    before it starts (not state a worker thread sets and restores)."""
    from engine import integrator
    orig = integrator.light_modes

    def modes(ctx, reflection=False):
        m = orig(ctx, reflection)
        m[m == integrator.MODE_MIS] = integrator.MODE_CONTINUATION
        return m
    monkeypatch.setattr(integrator, "light_modes", modes)
    # (a lamp with Diffuse off: no shadow rays, the continuation counts it in full)
    monkeypatch.setattr(integrator, "REFLECTION_ONLY_SAMPLING", False)


def pytest_sessionstart(session):
    """Under pytest-xdist (`make test` runs `-n`), compile the render kernels once in the
    controlling process before its workers start: each worker then loads the cache in a
    few seconds instead of every worker compiling the same kernels at once (a fresh
    checkout's cold compile is 2-3 CPU minutes). xdist starts its workers in its own
    sessionstart hook, marked trylast, so this one runs first."""
    if os.environ.get("PYTEST_XDIST_WORKER") or not getattr(session.config.option,
                                                            "numprocesses", None):
        return
    from engine import jit
    # (pytest captures print() here: its terminal writer shows the line)
    say = session.config.pluginmanager.get_plugin("terminalreporter").write_line
    if jit.needs_compile():
        say(f"{jit.COMPILE_MESSAGE} (before the test workers start)")
    say(f"render kernels ready in {jit.ensure_compiled():.0f} s")

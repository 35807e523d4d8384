"""The kernel cache keeps other engine versions' folders while they may be in use (several
checkouts on one machine must not delete each other's compiled kernels), and removes
versions unused for long or beyond the most recent few (engine/jit.py)."""
import os

from engine import jit

DAY = 86400.0


def _version(root, name, age_days, now):
    path = root / name
    path.mkdir()
    (path / "k.nbc").write_bytes(b"x")
    os.utime(path, (now - age_days * DAY, now - age_days * DAY))
    return path


def test_prune_keeps_recent_versions_and_removes_old_or_surplus_ones(tmp_path):
    now = 1_000_000_000.0
    keep = "0" * 16
    (tmp_path / keep).mkdir()
    recent = [_version(tmp_path, f"{i:016x}", 0.1 * (i + 1), now) for i in range(1, 4)]
    stale = _version(tmp_path, "a" * 16, jit.KEEP_DAYS + 1, now)
    foreign = tmp_path / "not-a-stamp"
    foreign.mkdir()
    os.utime(foreign, (now - 100 * DAY, now - 100 * DAY))
    removed = jit._prune(str(tmp_path), keep, now=now)
    assert removed == [str(stale)]
    assert all(p.is_dir() for p in recent) and (tmp_path / keep).is_dir()
    assert foreign.is_dir()  # not ours: never touched


def test_prune_caps_the_number_of_versions(tmp_path):
    now = 1_000_000_000.0
    keep = "f" * 16
    (tmp_path / keep).mkdir()
    versions = [_version(tmp_path, f"{i:016x}", 0.01 * (i + 1), now)
                for i in range(jit.KEEP_VERSIONS + 3)]
    jit._prune(str(tmp_path), keep, now=now)
    left = sorted(p.name for p in tmp_path.iterdir())
    # The current one plus the KEEP_VERSIONS - 1 most recently used others.
    assert len(left) == jit.KEEP_VERSIONS
    assert [p.name for p in versions[:jit.KEEP_VERSIONS - 1]] == sorted(set(left) - {keep})


def test_the_current_cache_folder_is_marked_used():
    assert os.path.isdir(jit.CACHE_DIR)
    assert os.path.basename(jit.CACHE_DIR) == jit._STAMP

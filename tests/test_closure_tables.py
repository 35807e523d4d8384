"""The GGX albedo tables (engine/closures/ggx_tables.npz) and the kernel cache keyed on them."""
import pytest  # noqa: F401

from engine import jit


def test_kernel_cache_stamp_follows_the_tables(tmp_path, monkeypatch):
    """numba freezes the tables (global arrays) into the machine code it caches: new tables
    must mean a new cache folder, as new kernel sources do."""
    pkg = tmp_path / "engine"
    (pkg / "closures").mkdir(parents=True)
    (pkg / "closures" / "k.py").write_text("@kernel\ndef f():\n    return 1\n")
    (pkg / "closures" / "t.npz").write_bytes(b"one")
    monkeypatch.setattr(jit, "__file__", str(pkg / "jit.py"))
    before = jit._engine_stamp()
    assert jit._engine_stamp() == before
    (pkg / "closures" / "t.npz").write_bytes(b"two")
    assert jit._engine_stamp() != before

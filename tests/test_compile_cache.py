"""The tests' shared compilation cache (tests/conftest.py) survives a torn entry.

JAX writes its persistent-cache files without a lock, so one pytest-xdist worker can read a file
another worker is still writing. JAX then warns and compiles the program itself; the suite's
warnings-as-errors must not turn that into a failed test (CI, 2026-12-04).
"""

import os
import time

import jax
import jax.numpy as jnp
import numpy as np
import pytest


def test_a_truncated_cache_entry_is_compiled_again_not_an_error():
    folder = jax.config.jax_compilation_cache_dir
    if not folder:
        pytest.skip("the persistent compilation cache is off (JAX_COMPILATION_CACHE_DIR=off)")
    salt = float(time.time_ns() % 1_000_003)  # a program no earlier run has cached

    def _torn_entry_probe(x):
        return x * salt + 1.0

    probe = jax.jit(_torn_entry_probe)
    x = jnp.arange(3.0)
    before = set(os.listdir(folder))
    np.testing.assert_allclose(probe(x), np.arange(3.0) * salt + 1.0)
    written = [n for n in set(os.listdir(folder)) - before if n.startswith("jit__torn_entry_probe") and n.endswith("-cache")]
    assert len(written) == 1, written
    with open(os.path.join(folder, written[0]), "wb"):
        pass  # what a reader sees while another process has only opened the file for writing

    jax.clear_caches()
    np.testing.assert_allclose(probe(x), np.arange(3.0) * salt + 1.0)  # warned and ignored
    jax.clear_caches()
    with pytest.warns(UserWarning, match="Error reading persistent compilation cache entry"):
        np.testing.assert_allclose(probe(x), np.arange(3.0) * salt + 1.0)

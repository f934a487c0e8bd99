"""Test configuration: float64 everywhere (gradient checks) and explicit PRNG keys."""

import os

import jax
import pytest

jax.config.update("jax_enable_x64", True)
# The command line keeps compiled programs in ~/.cache unless told otherwise: not from the tests
# (test_cli.py checks the cache in a subprocess of its own).
os.environ["JAXTRACK_CACHE_DIR"] = "off"

SHARED_DATA = os.path.join(os.path.dirname(__file__), "..", "..", "shared", "data")


class GetKey:
    """Fresh PRNG keys from one seed by fold-in (the seed is printed on failure)."""

    def __init__(self, seed: int):
        self.seed = seed
        self.count = 0
        self.base = jax.random.key(seed)

    def __call__(self):
        self.count += 1
        return jax.random.fold_in(self.base, self.count)


@pytest.fixture
def getkey():
    """Per-test key source; the seed is fixed (1234) so failures reproduce."""
    return GetKey(1234)


@pytest.fixture(scope="session")
def shared_data():
    path = os.path.abspath(SHARED_DATA)
    if not os.path.isdir(path):
        pytest.skip("../shared/data is absent")
    return path


@pytest.fixture(autouse=True)
def _release_compiled_programs(request):
    """Drop the compiled programs after every slow test. A process that keeps every program of
    the slow suite runs out of memory maps (vm.max_map_count is 65530 here) inside LLVM, which
    aborts the whole run; the benchmarks clear their caches for the same reason. The default
    suite keeps its programs: its modules share many of them, and clearing cost it 2.5 minutes."""
    yield
    if request.node.get_closest_marker("slow") is not None:
        jax.clear_caches()

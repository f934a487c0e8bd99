"""Test configuration: float64 everywhere (gradient checks) and explicit PRNG keys."""

import os

import jax
import pytest

jax.config.update("jax_enable_x64", True)
# The command line keeps compiled programs in ~/.cache unless told otherwise: not from the tests
# (test_cli.py checks the cache in a subprocess of its own).
os.environ["JAXTRACK_CACHE_DIR"] = "off"
# The tests' own compiled programs are kept on disk (JAX's persistent cache), shared by the
# pytest-xdist workers and by later runs: half of a cold test run is XLA compiling programs that
# another test or worker already compiled. JAX_COMPILATION_CACHE_DIR chooses the folder ("off":
# none); .ci/run points the notebooks' kernels at the same one. Every program is kept, however
# quick to compile: a worker then loads the small programs the other compiled (docs/testing.md).
_CACHE = os.environ.get("JAX_COMPILATION_CACHE_DIR", os.path.join(os.path.dirname(__file__), "..", ".pytest_jax_cache"))
if _CACHE.strip().lower() not in ("", "off"):
    jax.config.update("jax_compilation_cache_dir", os.path.abspath(_CACHE))
    jax.config.update("jax_persistent_cache_min_compile_time_secs", 0.0)
else:
    jax.config.update("jax_compilation_cache_dir", None)


def pytest_configure(config):
    """The default suite (``-m 'not slow'``, the addopts) compiles at XLA's backend optimisation
    level 0: its tests run tiny problems, most of their time is XLA compiling them, and level 0
    compiles in about half the time (docs/testing.md). The slow suite, the notebooks, the
    benchmarks and the library itself keep XLA's default, under which the filters run several
    times faster. An ``XLA_FLAGS`` that already names a level is left alone. Set here, before JAX
    starts its backend; the pytest-xdist workers inherit it."""
    flags = os.environ.get("XLA_FLAGS", "")
    if config.getoption("markexpr", "") == "not slow" and "xla_backend_optimization_level" not in flags:
        os.environ["XLA_FLAGS"] = f"{flags} --xla_backend_optimization_level=0".strip()


def pytest_xdist_auto_num_workers(config):
    """``-n auto``: one worker per core this process may use, at most 4 (each holds 2-4 GiB of
    compiled programs)."""
    return max(1, min(4, len(os.sched_getaffinity(0)) if hasattr(os, "sched_getaffinity") else os.cpu_count() or 1))

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


def _memory_maps_in_use() -> int | None:
    """How many memory maps this process holds (Linux), or None where that cannot be read."""
    try:
        with open("/proc/self/maps", "rb") as maps:
            return sum(1 for _ in maps)
    except OSError:
        return None


def _memory_map_limit() -> int:
    try:
        with open("/proc/sys/vm/max_map_count") as limit:
            return int(limit.read())
    except (OSError, ValueError):
        return 65530


MEMORY_MAP_LIMIT = _memory_map_limit()


@pytest.fixture(autouse=True)
def _release_compiled_programs(request):
    """Drop the compiled programs after every slow test, and after any test that leaves the
    process holding over half of its memory-map limit. A process that keeps every compiled
    program runs out of memory maps (vm.max_map_count is 65530 here) inside LLVM, which aborts
    the whole run ("LLVM compilation error: Cannot allocate memory"); the benchmarks clear their
    caches for the same reason. Otherwise the programs are kept: test modules share many of
    them, and clearing after every test cost the default suite 2.5 minutes."""
    yield
    maps = _memory_maps_in_use()
    if request.node.get_closest_marker("slow") is not None or (maps is not None and maps > MEMORY_MAP_LIMIT // 2):
        jax.clear_caches()


@pytest.fixture(scope="session")
def walk_and_prior():
    """A 60-frame synthetic walk and an unfitted 2-D GPDM prior on it (``helpers.walk_and_gpdm_prior``)."""
    from helpers import walk_and_gpdm_prior

    return walk_and_gpdm_prior()


@pytest.fixture(scope="session")
def walk(walk_and_prior):
    return walk_and_prior[0]


@pytest.fixture(scope="session")
def gpdm_prior(walk_and_prior):
    return walk_and_prior[1]

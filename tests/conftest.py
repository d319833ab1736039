import atexit
import os
import shutil
import sys
import tempfile

from bdft.kernels import pin_numeric_kernels

# the tests run the numerical kernels the commands run (OpenBLAS's Haswell kernels, NumPy's
# x86-64-v3 loops; bdft/kernels.py), before NumPy loads: the designs' nonsmooth tuning and
# the synthesis's SDPs turn last-bit differences into other controllers, and a verdict
# measured on one CPU's own kernels (AVX-512 loops) was not the one another CPU (AVX2 only)
# reached. Pinned, every x86-64 machine with AVX2 and FMA runs the same instructions
pin_numeric_kernels()

# under pytest-xdist each worker gets its share of the cores for its BLAS threads (one each
# for two workers on two cores), set before numpy loads OpenBLAS and passed on to the
# commands the tests start; a count the user set is kept. Without it two workers ran four
# BLAS threads on two cores, and small-matrix work spun against itself. Every thread count
# gives the same verdicts (the suite is also run with OPENBLAS_NUM_THREADS=1, and
# test_same_bytes runs commands under 1, 2 and 4 threads).
_WORKERS = int(os.environ.get("PYTEST_XDIST_WORKER_COUNT", "1") or 1)
if _WORKERS > 1:
    _SHARE = str(max(1, (os.cpu_count() or 1) // _WORKERS))
    for _var in ("OPENBLAS_NUM_THREADS", "OMP_NUM_THREADS", "MKL_NUM_THREADS"):
        os.environ.setdefault(_var, _SHARE)
    if "numpy" in sys.modules:  # loaded before this file: limit the running pools too
        from threadpoolctl import threadpool_limits

        threadpool_limits(int(os.environ["OPENBLAS_NUM_THREADS"]), user_api="blas")

import matplotlib  # noqa: E402

matplotlib.use("Agg")
os.environ.setdefault("MPLBACKEND", "Agg")

# the commands keep results in a cache by default: the tests use a fresh one of their own
# (never the user's), removed when the test process ends
_CACHE = tempfile.mkdtemp(prefix="bdft-test-cache-")
os.environ["BDFT_CACHE_DIR"] = _CACHE
atexit.register(shutil.rmtree, _CACHE, ignore_errors=True)


def pytest_collection_modifyitems(session, config, items):
    """The files holding a test marked ``slow`` first, in their collected order: pytest-xdist
    (``--dist loadfile``) deals whole files to its workers in this order, and the longest
    started last would run alone at the end."""
    slow = {item.path for item in items if item.get_closest_marker("slow")}
    items.sort(key=lambda item: item.path not in slow)


def pytest_collection_finish(session):
    """Under pytest-xdist, each worker compiles its share of the compiled kernels before its
    first test and waits for the others' (:func:`numba_builds.build_share`): each kernel is
    compiled once in a clean checkout, not once per worker (in a warm one the shares load
    from Numba's cache in a second)."""
    worker = os.environ.get("PYTEST_XDIST_WORKER", "")
    if _WORKERS > 1 and worker.startswith("gw"):
        from numba_builds import build_share

        build_share(int(worker[2:]), _WORKERS)

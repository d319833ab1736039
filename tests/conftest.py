import atexit
import os
import shutil
import tempfile

import matplotlib

matplotlib.use("Agg")
os.environ.setdefault("MPLBACKEND", "Agg")

# the commands keep results in a cache by default: the tests use a fresh one of their own
# (never the user's), removed when the test process ends
_CACHE = tempfile.mkdtemp(prefix="bdft-test-cache-")
os.environ["BDFT_CACHE_DIR"] = _CACHE
atexit.register(shutil.rmtree, _CACHE, ignore_errors=True)

"""The job runner's forkserver preload (:mod:`api.preload`): matplotlib and numba's runtime set
up once, in a process that may still fork – no thread started – and only there (the server
process itself never loads numba)."""

from __future__ import annotations

import subprocess
import sys

from waits import HANG_S

PROBE = """
import os, sys
import numpy, scipy.linalg  # their BLAS threads (OpenBLAS's own, fork-safe) exist before
def threads():
    return len(os.listdir("/proc/self/task"))
before = threads()
from ris_planner.runtime.kernels import compiled_code_loaded
import api.preload
assert compiled_code_loaded(), "numba's runtime is not set up"
assert "matplotlib.pyplot" in sys.modules
import matplotlib
assert matplotlib.get_backend().lower() == "agg", matplotlib.get_backend()
assert threads() == before, (before, threads())
from numba.np.ufunc import parallel
assert not parallel._is_initialized, "the preload started numba's thread pool"
pid = os.fork()  # a job: a fork of the preloaded process runs a parallel kernel and draws
if pid == 0:
    import numpy as np
    from ris_planner.inversion import crb, ldl
    f = np.zeros((28, 4096))
    for i in range(7):
        f[ldl.packed_index(7)[(i, i)]] = 2.0  # 2·I: the CRB's diagonal is 1/2
    d, singular, _ = crb.fast_diagonal(f, 7, engine="numba")  # a parallel kernel
    ok = bool(np.all(d == 0.5) and not singular.any())
    import matplotlib.pyplot as plt
    fig, ax = plt.subplots()
    ax.plot([0, 1], [0, 1])
    fig.canvas.draw()
    os._exit(0 if ok else 3)
_, status = os.waitpid(pid, 0)
assert os.WEXITSTATUS(status) == 0, status
print("ok")
"""


def test_preload_sets_up_matplotlib_and_numba_without_a_thread() -> None:
    done = subprocess.run(
        [sys.executable, "-c", PROBE], capture_output=True, text=True, timeout=HANG_S, check=False
    )
    assert done.returncode == 0 and done.stdout.strip() == "ok", done.stderr[-2000:]


def test_the_server_process_does_not_load_the_preload() -> None:
    code = (
        "import sys\n"
        "import api.main, api.worker\n"
        "assert 'api.preload' not in sys.modules\n"
        "assert 'numba' not in sys.modules, 'the server imported numba'\n"
        "assert 'matplotlib' not in sys.modules, 'the server imported matplotlib'\n"
    )
    done = subprocess.run(
        [sys.executable, "-c", code], capture_output=True, text=True, timeout=HANG_S, check=False
    )
    assert done.returncode == 0, done.stderr[-2000:]

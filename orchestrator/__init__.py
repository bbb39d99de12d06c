"""Orchestrator: scenarios, FMU build, the fmpy co-simulation master, Rerun traces, CLI.

One BLAS thread. Every co-simulation step is a handful of small matrix-vector products,
for which one BLAS thread is faster than several (on a shared 2-core machine eigenvalue
problems of a 20-vehicle fleet ran 12x faster with one thread), and the thread count
changes the last bits of a result: the same seed gives the same traces only with the same
count. Importing this package sets OPENBLAS_NUM_THREADS / OMP_NUM_THREADS /
MKL_NUM_THREADS to 1 unless the user set them, and applies OPENBLAS_NUM_THREADS (or 1) to
the BLAS libraries already loaded (numpy's and scipy's, through threadpoolctl), so it
holds whatever was imported before (a BLAS loaded after this package reads the variable).
"""
import os as _os

for _var in ("OPENBLAS_NUM_THREADS", "OMP_NUM_THREADS", "MKL_NUM_THREADS"):
    _os.environ.setdefault(_var, "1")


def _limit_blas_threads() -> None:
    """A BLAS library loaded before the variables above were set ignores them: apply the
    count to the loaded ones (a library loaded later reads the variable itself)."""
    import sys
    if "numpy" not in sys.modules and "scipy" not in sys.modules:
        return
    from threadpoolctl import threadpool_limits
    try:
        n = max(1, int(_os.environ["OPENBLAS_NUM_THREADS"]))
    except ValueError:
        n = 1
    threadpool_limits(limits=n, user_api="blas")


_limit_blas_threads()

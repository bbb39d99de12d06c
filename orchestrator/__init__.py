"""Orchestrator: scenarios, FMU build, the fmpy co-simulation master, Rerun traces, CLI.

Importing it sets OPENBLAS_NUM_THREADS / OMP_NUM_THREADS / MKL_NUM_THREADS to 1 unless the
user set them: every co-simulation step is a handful of small matrix-vector products, for
which one BLAS thread is faster than several (on a shared 2-core machine eigenvalue
problems of a 20-vehicle fleet ran 12x faster with one thread). Set the variables to
override. It only takes effect if numpy was not imported before.
"""
import os as _os

for _var in ("OPENBLAS_NUM_THREADS", "OMP_NUM_THREADS", "MKL_NUM_THREADS"):
    _os.environ.setdefault(_var, "1")

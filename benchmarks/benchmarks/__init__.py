"""The asv (airspeed velocity) suite of vesicle-wrinkling: the kernels that set a run's cost.

Run from ``benchmarks/`` (where ``asv.conf.json`` is): ``asv run --python=same --quick`` times the working tree in
the current environment; docs/howto/benchmarks.md says how to record and compare commits.
"""

import os

# One BLAS/OpenMP thread, as the workflow runs (fft_workers: 1): a spinning BLAS thread slows the FFTs 5-10x on a
# shared 2-core machine (benchmarks/bench_step.py). Set before NumPy is imported by any benchmark module.
os.environ.setdefault("OPENBLAS_NUM_THREADS", "1")
os.environ.setdefault("OMP_NUM_THREADS", "1")

"""ptam: Parallel Tracking and Mapping (Klein & Murray 2007) and its extensions, in Python."""

import os

# The tracker and the mapper are two threads on their own; a multi-threaded BLAS inside either of them
# oversubscribes the cores (a 174x174 Cholesky took 423 ms instead of 0.2 ms on a loaded 2-core machine).
# Takes effect when ptam is imported before numpy, as the `ptam` command does; a user's setting wins.
for _var in ("OPENBLAS_NUM_THREADS", "OMP_NUM_THREADS", "MKL_NUM_THREADS"):
    os.environ.setdefault(_var, "1")

__version__ = "0.1.0"

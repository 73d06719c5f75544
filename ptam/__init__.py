"""ptam: Parallel Tracking and Mapping (Klein & Murray 2007) and its extensions, in Python."""

import os

# The tracker and the mapper are two threads on their own; a multi-threaded BLAS inside either of them
# oversubscribes the cores (a 174x174 Cholesky took 423 ms instead of 0.2 ms on a loaded 2-core machine).
# OpenCV's thread pool likewise: the mapper's Canny (Agility §4.3) split over two threads cost 45 % more CPU
# than on one, time taken from the tracker's core. Takes effect when ptam is imported before numpy and cv2, as
# the `ptam` command does; a user's setting wins.
for _var in ("OPENBLAS_NUM_THREADS", "OMP_NUM_THREADS", "MKL_NUM_THREADS", "OPENCV_FOR_THREADS_NUM"):
    os.environ.setdefault(_var, "1")

__version__ = "0.1.0"

"""One BLAS thread for the simulator/diagnosis tests when run on their own: their least-squares
problems are small, and threaded BLAS on a loaded 2-core machine made them several times slower.
(Only effective when numpy is not loaded yet, i.e. `pytest tests/python/sim`.)"""

import os

for _v in ("OMP_NUM_THREADS", "OPENBLAS_NUM_THREADS", "MKL_NUM_THREADS"):
    os.environ.setdefault(_v, "1")

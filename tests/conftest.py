import os
import sys
from pathlib import Path

# One BLAS thread a process: the suite runs a worker per core (pytest-xdist), and each worker's
# OpenBLAS would otherwise start a thread per core too (2 × 2 on this machine: 5:22 against 3:58
# for the suite). Set before numpy is first imported; subprocesses inherit it.
for _threads in ("OPENBLAS_NUM_THREADS", "OMP_NUM_THREADS", "MKL_NUM_THREADS"):
    os.environ.setdefault(_threads, "1")

sys.path.insert(0, str(Path(__file__).parent))

"""One BLAS thread for the fits and the designs.

Their linear algebra is on small matrices: a record's Jacobian (its samples × at most nine
unknowns), which ``scipy.optimize.least_squares`` factors by SVD at every iteration, and
Fisher matrices of nine by nine. At that size OpenBLAS's threads cost more than they save,
and where other work shares the cores (several fits at once, one Dask worker per core, a
training run beside) they contend for them: on the 2-core machine with two other jobs
running, one SVD of a 2094 × 7 Jacobian took 37 ms with OpenBLAS's default threads and
0.14 ms with one, and :func:`fricenv.identify` on six designed-excitation records took 50 s
against 20 s. So :func:`one_blas_thread` holds the BLAS libraries the process has loaded
(numpy's and SciPy's) to one thread while a fit or a design runs, through ``threadpoolctl``
(the ``identify`` extra), and gives the caller's setting back afterwards.
"""

from __future__ import annotations

import contextlib
from collections.abc import Iterator


@contextlib.contextmanager
def one_blas_thread() -> Iterator[None]:
    """Within this block the loaded BLAS libraries run on one thread each."""
    try:
        from threadpoolctl import threadpool_limits
    except ImportError:  # pragma: no cover - threadpoolctl is in the identify extra
        raise ImportError("identify needs threadpoolctl: pip install 'fricenv[identify]'"
                          ) from None
    with threadpool_limits(limits=1, user_api="blas"):
        yield

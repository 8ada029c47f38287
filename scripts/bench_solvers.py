"""``fricenv bench solvers``, run from a checkout: ``python scripts/bench_solvers.py [OPTIONS]``.

The benchmark lives in :mod:`fricenv.bench.solvers`; this file only runs it through the
``fricenv`` command (progress lines on stderr, ``--quiet`` silences them).
"""

import sys

from fricenv.cli import main

sys.exit(main(["bench", "solvers", *sys.argv[1:]]))

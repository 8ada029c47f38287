"""``fricenv bench sweep``, run from a checkout: ``python scripts/bench_sweep.py [OPTIONS]``.

The benchmark lives in :mod:`fricenv.bench.sweep`; this file only runs it through the
``fricenv`` command (progress lines on stderr, ``--quiet`` silences them).
"""

import sys

from fricenv.cli import main

sys.exit(main(["bench", "sweep", *sys.argv[1:]]))

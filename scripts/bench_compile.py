"""``fricenv bench compile``, run from a checkout: ``python scripts/bench_compile.py [OPTIONS]``.

The benchmark lives in :mod:`fricenv.bench.compile`; this file only runs it through the
``fricenv`` command (progress lines on stderr, ``--quiet`` silences them).
"""

import sys

from fricenv.cli import main

sys.exit(main(["bench", "compile", *sys.argv[1:]]))

"""``fricenv bench env``, run from a checkout: ``python scripts/bench_env.py [OPTIONS]``.

The benchmark lives in :mod:`fricenv.bench.env`; this file only runs it through the
``fricenv`` command (progress lines on stderr, ``--quiet`` silences them).
"""

import sys

from fricenv.cli import main

sys.exit(main(["bench", "env", *sys.argv[1:]]))

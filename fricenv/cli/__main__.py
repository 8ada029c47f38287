"""``python -m fricenv.cli``: the same as the ``fricenv`` command."""

import sys

from fricenv.cli import main

sys.exit(main())

"""``python -m fricenv.atlas``: the atlas's command line (:mod:`fricenv.atlas.cli`)."""

import sys

from .cli import main

if __name__ == "__main__":
    sys.exit(main())

"""``python -m fricenv.atlas``: the atlas's command line, :mod:`fricenv.cli.atlas` (the
same as ``fricenv atlas``). A program: nothing imports it, and no other module of the
atlas package imports the command line."""

import sys

from fricenv.cli.atlas import module_main

if __name__ == "__main__":
    sys.exit(module_main())

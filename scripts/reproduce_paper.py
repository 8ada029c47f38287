#!/usr/bin/env python
"""Reproduce the paper's Figs. 2-10 and write a comparison report (see fricenv.reproduce).

Same as the ``fricenv-reproduce`` entry point: ``python scripts/reproduce_paper.py --quick``.
"""

import sys

from fricenv.reproduce import main

if __name__ == "__main__":
    sys.exit(main())

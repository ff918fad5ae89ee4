"""``python -m exo_bench.bench.cli``: the command line."""

import sys

from exo_bench.bench.cli.app import main

if __name__ == "__main__":  # not when the API reference (autodoc) imports this module
    sys.exit(main())

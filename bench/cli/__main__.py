"""``python -m exo_bench.bench.cli``: the command line."""

import sys

from exo_bench.bench.cli.app import main

sys.exit(main())

"""``python -m sss_lab``: the project's command line."""

import sys

from .addon.cli import main

if __name__ == "__main__":  # not when a worker process started with spawn imports it
    sys.exit(main())

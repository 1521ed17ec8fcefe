"""``python -m sss_lab``: the project's command line."""

import sys

from .addon.cli import main

sys.exit(main())

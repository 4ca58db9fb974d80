"""``python -m planarize``: the ``planarize`` command line."""

import sys

from .cli.main import main

sys.exit(main())

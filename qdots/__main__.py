"""``python -m qdots``: the ``qdots`` command line."""

import sys

from .cli.main import main

sys.exit(main())

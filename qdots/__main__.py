"""``python -m qdots``: the ``qdots`` command line."""

import sys

from .cli import main

sys.exit(main())

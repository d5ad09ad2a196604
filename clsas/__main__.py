"""``python -m clsas``: see :mod:`clsas.cli`."""

import sys

from .cli import main

sys.exit(main())

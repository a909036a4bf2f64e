"""``python -m pamkin``: the ``pamkin`` command."""

import sys

from .cli import main

sys.exit(main())

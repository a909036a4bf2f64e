"""``python -m pamkin.cli``: the ``pamkin`` command."""

import sys

from . import main

sys.exit(main())

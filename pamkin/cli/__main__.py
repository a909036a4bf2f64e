"""``python -m pamkin.cli``: the ``pamkin`` command."""

import sys

from pamkin.cli import main

sys.exit(main())

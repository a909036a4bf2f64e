"""``python -m pamkin``: the ``pamkin`` command."""

import sys

from pamkin.cli import main

if __name__ == "__main__":      # not when a spawned process imports it (the background audit)
    sys.exit(main())

"""``python -m quatarray``: the ``quatarray`` command (see `quatarray.cli`)."""

import sys

from .cli import main

if __name__ == "__main__":
    sys.exit(main())

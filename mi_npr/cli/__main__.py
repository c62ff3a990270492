"""``python -m mi_npr.cli``: the ``mi-npr`` command."""

import sys

from . import main

if __name__ == "__main__":
    sys.exit(main())

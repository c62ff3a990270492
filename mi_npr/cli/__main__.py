"""``python -m mi_npr.cli``: the ``mi-npr`` command."""

import sys

from . import main

sys.exit(main())

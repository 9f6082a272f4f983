"""``python -m merger.cli``: the ``merger`` command."""

import sys

from . import main

sys.exit(main())

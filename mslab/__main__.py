"""``python -m mslab``: the ``mslab`` command line."""

import sys

from mslab.cli import main

sys.exit(main())

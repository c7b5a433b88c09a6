import sys

from mslab.cli import main

sys.exit(main())

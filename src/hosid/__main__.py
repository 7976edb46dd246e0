"""Run the command line with ``python -m hosid``."""

import sys

from hosid.cli import main

sys.exit(main())

"""Run the command line with ``python -m hosid``."""

import sys

from hosid.cli import main

if __name__ == "__main__":
    sys.exit(main())

"""`python -m planarcal` runs the command line."""

import sys

from planarcal.cli import main

sys.exit(main())

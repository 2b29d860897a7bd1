"""`python -m attend` runs the command line (same as `attend`)."""

import sys

from attend.cli import main

sys.exit(main())

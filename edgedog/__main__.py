"""`python -m edgedog` is the `edgedog` command."""

import sys

from edgedog.cli import main

sys.exit(main())

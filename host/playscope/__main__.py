"""`python -m playscope`: the same entry point as the `playscope` script (playscope.cli)."""

import sys

from .cli import main

sys.exit(main())

"""`python -m imufuse`: the imufuse command line (imufuse.cli)."""
import sys

from .cli import main

sys.exit(main())

"""``python -m bayesdrag``: the same entry point as the ``bayesdrag`` command."""
import sys

from .cli import main

sys.exit(main())

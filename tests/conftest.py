"""Shared test set-up: the tests folder on the import path (for ``support`` and ``acceptance``
helpers) and the fixtures by domain (``tests/fixtures``).

Layout: ``unit/`` (one module's behaviour), ``integration/`` (commands, files, several layers),
``acceptance/`` (statistical validation suites; their long versions are marked ``slow``)."""
import sys
from pathlib import Path

TESTS = Path(__file__).resolve().parent
if str(TESTS) not in sys.path:
    sys.path.insert(0, str(TESTS))

pytest_plugins = ["fixtures.physics", "fixtures.shell155"]

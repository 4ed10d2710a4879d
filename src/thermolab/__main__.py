"""Allow ``python -m thermolab``."""

import sys

from thermolab.cli import main

sys.exit(main())

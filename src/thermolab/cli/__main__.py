"""Allow ``python -m thermolab.cli``."""

import sys

from thermolab.cli import main

sys.exit(main())

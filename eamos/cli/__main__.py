"""``python -m eamos.cli`` is ``eamos``."""

import sys

from eamos.cli.main import main

sys.exit(main())

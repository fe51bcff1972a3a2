"""``python -m breastcore``: the command line."""

import sys

from breastcore.cli import main

sys.exit(main())

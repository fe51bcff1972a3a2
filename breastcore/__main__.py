"""``python -m breastcore``: the command line."""

import sys

from breastcore.cli.main import main

sys.exit(main())

"""``python -m optcal``: the same command line as the ``optcal`` script (optcal.app.cli)."""

import sys

from optcal.app.cli import main

sys.exit(main())

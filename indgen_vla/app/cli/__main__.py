"""``python -m indgen_vla.app.cli``: the ``indgen`` command without its console script."""

import sys

from indgen_vla.app.cli import main

sys.exit(main())

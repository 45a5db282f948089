"""``python -m topomap.app.report SWEEP_DIR``: rebuild a sweep's report (:mod:`.cli`)."""

import sys

from .cli import main

sys.exit(main())

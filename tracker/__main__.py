"""``python -m tracker``: the same program as the ``pose-tracker`` command (and it calls itself that)."""
import sys

from tracker.app.cli import main

sys.exit(main())

"""``python -m tracker``: the same program as the ``pose-tracker`` command (and it calls itself that)."""
from tracker.app.cli import run

run()

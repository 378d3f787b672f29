"""Defaults that the API, the command line and the experiment runner share: every one is the default of a setting
declared in :mod:`tracker.app.schema` (this module names the ones scripts import)."""
from tracker.engine.config import TRACK_ANNEALING_LAYERS

__all__ = ["TRACK_ANNEALING_LAYERS"]

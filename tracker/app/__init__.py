"""The application layer: the public API, the command line and the experiment runner.

Importing it hands the registries (priors, likelihoods, mocap readers) the one function that fills them from
the plugins before their first lookup (:func:`tracker.app.plugins.load_plugins`).
"""
from tracker.app import plugins as _plugins  # noqa: F401  (sets the registries' fill)

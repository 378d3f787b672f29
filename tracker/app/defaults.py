"""Defaults that the API, the command line and the experiment runner share (a module that imports nothing, so
that the command line's help can state them without loading the tracker)."""

#: Annealing layers per frame that :func:`tracker.app.api.track` (and the command line, and experiment files that
#: leave ``annealing_layers`` unset) uses when none are asked for: 3 won in ``docs/methods_report.md`` ("the
#: annealed filter") for the zero-velocity baseline and the paced CRBM on people the priors were not trained on,
#: and the FCRBM's tuning fold with its style inferred by mixture tracking (``docs/methods_report.md``).
#: The engine's own :class:`~tracker.engine.filter.FilterConfig` default stays plain SIR.
TRACK_ANNEALING_LAYERS = 3

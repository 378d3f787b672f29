"""The former name of :mod:`tracker.engine.multiple_models` (the filter's multiple-model machinery, mixture
tracking), kept for one version so that plugins importing it keep working; import
``tracker.engine.multiple_models`` instead. (The prior that mixes motion models is :mod:`priors.mixture`.)

Imported from outside the toolkit's own packages it warns (:class:`DeprecationWarning`, attributed to the
importing line); the toolkit's own modules that still import it are moving to the new name."""
import sys
import warnings

from tracker.engine.multiple_models import (ComponentPrior, Mixing, Mixture, MixtureTracking, mixing_of,  # noqa: F401
                                            mixture_weights, resample_components, switching)

_OWN = ("tracker.", "priors.", "likelihoods.", "data_tools.")


def _warn_outside_importer() -> None:
    frame = sys._getframe(2)  # past this function and the module's own frame: the import machinery or the importer
    while frame is not None and frame.f_globals.get("__name__", "").startswith(("importlib", "_frozen_importlib")):
        frame = frame.f_back
    if frame is None or frame.f_globals.get("__name__", "").startswith(_OWN):
        return
    warnings.warn_explicit("tracker.engine.mixture is renamed tracker.engine.multiple_models; the old name will be "
                           "removed", DeprecationWarning, frame.f_code.co_filename, frame.f_lineno,
                           module=frame.f_globals.get("__name__"),
                           registry=frame.f_globals.setdefault("__warningregistry__", {}))


_warn_outside_importer()

"""The former place of the mixture's ``components`` option, now :mod:`priors.mixture_components`: only
:func:`with_model_paths` is kept here, for one version, answered through the registry so that the engine imports
no plugin. Call :meth:`tracker.engine.registry.PriorEntry.located` instead."""
from __future__ import annotations

from typing import Callable

from tracker.engine.registry import PRIORS


def with_model_paths(value: str, owner: str, path: Callable[[str], str]) -> str:
    """``value`` (the mixture's ``components`` option) with each component's ``model=FILE`` replaced by
    ``path(FILE)``; ``value`` itself when no component names a model file."""
    entry = PRIORS.get("mixture")
    return entry.located({"components": value}, path, owner)["components"]

"""Finding plugins: the built-in prior and likelihood modules (each package lists its own), entry points, and modules
named by the user.

Importing a plugin module runs its ``register_prior`` / ``register_likelihood``
decorators (:mod:`tracker.engine.registry`).
"""
from __future__ import annotations

import importlib
import importlib.util
import sys
from importlib.metadata import entry_points
from pathlib import Path

from tracker.core.errors import InputError
from data_tools.motion.readers import READERS
from tracker.engine.registry import LIKELIHOODS, PRIORS, LikelihoodEntry, PriorEntry

#: Entry-point group through which an installed package adds priors or likelihoods.
ENTRY_POINT_GROUP = "pose_tracker.plugins"
_BUILTIN_PACKAGES = ("priors", "likelihoods")
_loaded = False
_loading = False


def load_plugins() -> None:
    """Import the modules each built-in plugin package lists in ``BUILTIN_MODULES`` (the ones that register its
    priors or likelihoods) and every ``pose_tracker.plugins`` entry point (once per process)."""
    global _loaded, _loading
    if _loaded or _loading:  # a plugin module that looks a name up while it is imported: the table is filling
        return
    _loading = True
    try:
        _import_plugins()
    finally:
        _loading = False
    _loaded = True


def _import_plugins() -> None:
    for package in _BUILTIN_PACKAGES:
        for module in importlib.import_module(package).BUILTIN_MODULES:
            importlib.import_module(module)
    for ep in entry_points(group=ENTRY_POINT_GROUP):
        try:
            ep.load()
        except Exception as exc:  # noqa: BLE001 -- a broken third-party plugin must not take the tool down
            raise InputError(f"plugin entry point {ep.name} ({ep.value}) failed to load: "
                             f"{type(exc).__name__}: {exc}") from None


#: The registries fill themselves from the plugins before their first lookup, wherever it comes from.
PRIORS.fill = LIKELIHOODS.fill = READERS.fill = load_plugins


def prior_entry(name: str) -> PriorEntry:
    """The registered prior ``name`` (an :class:`InputError` naming the available ones if none is)."""
    return PRIORS.get(name)


def likelihood_entry(name: str) -> LikelihoodEntry:
    """The registered likelihood ``name`` (an :class:`InputError` naming the available ones if none is)."""
    return LIKELIHOODS.get(name)


def available_priors() -> list[str]:
    """Names of the registered priors (built-in and plugins)."""
    return PRIORS.names()


def available_likelihoods() -> list[str]:
    """Names of the registered likelihoods."""
    return LIKELIHOODS.names()


def import_plugin(spec: str) -> None:
    """Import a plugin by module name (``mypackage.myprior``) or file path (``./my_prior.py``)."""
    path = Path(spec)
    if path.suffix == ".py":
        if not path.is_file():
            raise InputError("plugin file not found", path)
        name = f"pose_tracker_plugin_{path.stem}"
        module_spec = importlib.util.spec_from_file_location(name, path)
        module = importlib.util.module_from_spec(module_spec)  # type: ignore[arg-type]
        sys.modules[name] = module
        module_spec.loader.exec_module(module)  # type: ignore[union-attr]
        return
    try:
        importlib.import_module(spec)
    except ModuleNotFoundError as exc:
        raise InputError(f"cannot import plugin module {spec!r} ({exc})") from None

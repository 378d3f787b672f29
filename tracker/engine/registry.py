"""Priors and likelihoods found by name: the extension points of the toolkit.

A plugin module registers a *builder* for its prior or likelihood; the API and
the command line look builders up here, and the command line's choices and
per-plugin options come from these entries. Built-in plugins are the modules
the ``priors`` and ``likelihoods`` packages list in ``BUILTIN_MODULES`` (each
registers itself on import; the application layer imports them,
:func:`tracker.app.plugins.load_plugins`);
a package of your own registers through the ``pose_tracker.plugins``
entry-point group, or any module can be imported with
``python -m tracker --plugin MODULE_OR_FILE``. This module holds only the
tables: the engine never imports a plugin.

A prior builder is called as ``build(context, model_files, options)`` and
returns a :class:`~tracker.engine.prior.MotionPrior`; a learned prior also
registers ``train(data, options, rng, progress, checkpoint)`` returning an
object with ``save(path)`` and ``summary()``. A likelihood builder is called as ``build(context, options)``
and returns a :class:`~tracker.engine.likelihood.Likelihood`. ``options`` is a
dict holding every declared :class:`Option`, checked and defaulted.
"""
from __future__ import annotations

import math
from dataclasses import dataclass, field
from functools import cached_property
from pathlib import Path
from typing import Any, Callable, Generic, Mapping, Protocol, Sequence, TypeVar, runtime_checkable

import numpy as np

from tracker.core.body import BodyModel
from tracker.core.cameras import CameraRig
from tracker.core.errors import InputError

@dataclass(frozen=True)
class Option:
    """One setting, declared once: its keyword ``name`` (``--name-with-dashes`` on the command line, the key of
    an experiment file's table and of ``result.json``), value type (``int``, ``float``, ``str`` or ``bool``),
    default, help text, optional bounds or choices, and the ``unit`` its values are in (``"mm"``, ``"frames"``,
    ...; empty for a pure number). The options of plugins and the settings of a run
    (:mod:`tracker.engine.config`, :mod:`tracker.app.schema`) are all of this one kind; ``many`` options hold a
    tuple of values (``views``: ``0,2`` on the command line, a list elsewhere)."""

    name: str
    type: type
    default: Any
    help: str
    minimum: float | None = None
    strict: bool = False
    choices: tuple = ()
    #: Largest value allowed (numbers): a scale far beyond any sensible setting overflows the arithmetic it feeds.
    maximum: float | None = None
    #: Checks a text option's value (raising :class:`InputError` with the rule, naming the option).
    check: Callable[[str, str], Any] | None = None
    #: What the default is, in words, where it is not simply ``default`` (e.g. it depends on the model file).
    default_note: str = ""
    #: The unit of the values (stated in help texts and documentation; keys carry no unit suffix).
    unit: str = ""
    #: Whether ``maximum`` itself is excluded.
    strict_max: bool = False
    #: A tuple of values of ``type`` (given as a list, or comma-separated text), each checked.
    many: bool = False

    def described(self) -> str:
        """The help text with the default (and its unit) stated, unless the text already states it."""
        if "(default" in self.help:
            return self.help
        if self.default_note:
            default = self.default_note
        elif self.default is None:
            return self.help
        elif self.type is bool:
            default = "on" if self.default else "off"
        else:
            default = _text(self.default)
            default += f" {self.unit}" if self.unit and self.unit != "%" else self.unit
        return f"{self.help} (default {default})"

    @property
    def flag(self) -> str:
        return "--" + self.name.replace("_", "-")

    @property
    def rule(self) -> str:
        """The bounds in words (``"at least 1 and at most 1000000"``), empty for an unbounded option."""
        bound = [] if self.minimum is None else \
            [f"{'greater than' if self.strict else 'at least'} {_text(self.minimum)}"]
        bound += [] if self.maximum is None else [f"{'less than' if self.strict_max else 'at most'} "
                                                  f"{_text(self.maximum)}"]
        return " and ".join(bound)

    def parse(self, value: Any, owner: str) -> Any:
        """``value`` converted to the option's type and checked; an :class:`InputError` names the owner and the
        option and states the rule."""
        if value is None:
            return None
        if self.many:
            try:
                items = value.split(",") if isinstance(value, str) else list(value)
            except TypeError:
                items = []
            if not items:
                raise InputError(f"{owner}: {self.name} must be a non-empty list of {_NOUNS[self.type]}s, "
                                 f"got {value!r}")
            return tuple(self._one(v.strip() if isinstance(v, str) else v, owner) for v in items)
        return self._one(value, owner)

    def _one(self, value: Any, owner: str) -> Any:
        try:
            if self.type is bool:
                if isinstance(value, str):
                    if value.lower() not in ("true", "false", "1", "0", "yes", "no"):
                        raise ValueError(value)
                    value = value.lower() in ("true", "1", "yes")
                elif not isinstance(value, (bool, int, np.integer)):
                    raise TypeError(value)
                out = bool(value)
            elif self.type is int:
                if isinstance(value, bool) or (isinstance(value, float) and not value.is_integer()):
                    raise ValueError(value)
                out = int(value)
            elif self.type is float:
                if isinstance(value, bool):
                    raise ValueError(value)
                out = float(value)
            else:
                if not isinstance(value, str):
                    raise TypeError(value)
                out = self.type(value)
        except (TypeError, ValueError, OverflowError):
            raise InputError(f"{owner}: {self.name} must be {_NOUNS.get(self.type, self.type.__name__)}, "
                             f"got {value!r}") from None
        if self.type in (int, float):
            if not math.isfinite(out):
                raise InputError(f"{owner}: {self.name} must be finite, got {value!r}")
            low = self.minimum is not None and (out < self.minimum or (self.strict and out == self.minimum))
            high = self.maximum is not None and (out > self.maximum or (self.strict_max and out == self.maximum))
            if low or high:
                raise InputError(f"{owner}: {self.name} must be {self.rule}, got {value!r}")
        if self.choices and out not in self.choices:
            raise InputError(f"{owner}: {self.name} must be one of {', '.join(map(str, self.choices))}, got {value!r}")
        if self.check is not None:
            self.check(out, owner)
        return out


_NOUNS = {int: "an integer", float: "a number", bool: "true or false", str: "text"}


def _text(value: Any) -> str:
    """A number as help texts and messages write it (``1000000``, ``0.5``)."""
    if isinstance(value, float):
        return format(value, "g") if abs(value) < 1e6 or not value.is_integer() else str(int(value))
    return str(value)


def resolve_options(owner: str, declared: Sequence[Option], given: Mapping[str, Any]) -> dict[str, Any]:
    """Every declared option, from ``given`` (checked) or its default; an undeclared name is refused."""
    known = {o.name: o for o in declared}
    unknown = [k for k in given if k not in known]
    if unknown:
        offered = ", ".join(known) or "none"
        raise InputError(f"{owner} takes no option {', '.join(map(repr, unknown))} (its options: {offered})")
    return {name: (o.parse(given[name], owner) if given.get(name) is not None else o.default)
            for name, o in known.items()}


@dataclass
class PriorContext:
    """What a prior builder may need about the sequence it will track.

    ``body_model`` and ``fps`` (Hz; ``None`` when the sequence states none);
    ``device`` for priors with a torch path; ``source`` names the sequence in
    messages. :meth:`step_std` is the per-dof RMS frame-to-frame change used as
    the random-walk scale, computed on first use by ``step_std_source`` (from
    training clips or the sequence's own file) so priors that do not need it
    cost nothing.
    """

    body_model: BodyModel
    fps: float | None
    device: str = "cpu"
    source: str | None = None
    step_std_source: Callable[[], np.ndarray] | None = None

    @cached_property
    def _step_std(self) -> np.ndarray:
        if self.step_std_source is None:
            raise InputError("this prior needs a random-walk scale, and none was given (training clips or "
                             "a step_std)", self.source)
        std = np.asarray(self.step_std_source(), float)
        if std.shape != (self.body_model.n_dofs,):
            raise InputError(f"random-walk scale has {std.shape} entries; the {self.body_model.name} model has "
                             f"{self.body_model.n_dofs} pose numbers", self.source)
        return std

    def step_std(self) -> np.ndarray:
        return self._step_std


@dataclass(frozen=True)
class TrainingData:
    """Pose clips (each ``T_i x D`` at ``fps`` Hz, retargeted to ``body_model``) and where they came from."""

    clips: tuple[np.ndarray, ...]
    fps: float
    body_model: BodyModel
    sources: tuple[str, ...] = ()

    @property
    def n_frames(self) -> int:
        return sum(len(c) for c in self.clips)


@dataclass(frozen=True)
class LikelihoodContext:
    """What a likelihood builder needs: the body model, the calibrated cameras of the tracked views, the torch
    device to score on (``"cpu"``: the CPU path; ``"cuda"``, ``"cuda:N"``: a likelihood's device path), and how
    many threads it may score with on the CPU."""

    body_model: BodyModel
    rig: CameraRig
    device: str = "cpu"
    threads: int = 1


@dataclass(frozen=True)
class ResolvedPrior:
    """What a prior is built from: its options (every declared one, checked or defaulted), the model files its
    builder is handed (paths, or models :func:`tracker.train` returned), and the model files its options name
    themselves (a mixture's ``crbm:model=crbm1.pt``), which a run records beside the others."""

    options: dict
    model_files: tuple[Any, ...] = ()
    named_files: tuple[Path, ...] = ()


@dataclass(frozen=True)
class GivenComponent:
    """One prior that a prior made of other priors is built from, as an experiment file's ``[[prior.components]]``
    table gives it: its registered ``prior``, its ``options`` as written there (already checked against that
    prior), and ``model_files``, how many of the composite prior's model files it takes, in order."""

    prior: str
    options: Mapping[str, Any]
    model_files: int = 0


@runtime_checkable
class Composition(Protocol):
    """How a prior made of other registered priors (its components; the mixture's) names them in one of its
    options. A prior entry carries it (:attr:`PriorEntry.composition`), so that the application reads, records
    and relocates such a prior without knowing how the option is written.

    ``option`` is the option's name; :meth:`written` writes components given as tables into that option's value;
    :meth:`located` replaces each model file that the value names by ``path(file)``; :meth:`resolve` completes
    the options and model files (what the prior takes when given none) and lists the files the options name."""

    option: str

    def written(self, components: Sequence[GivenComponent]) -> str:
        """The option's value naming ``components`` (each taking its count of the prior's model files)."""

    def located(self, value: str, path: Callable[[str], str], owner: str) -> str:
        """``value`` with each model file it names replaced by ``path(file)``; ``value`` itself when it names
        none. A refusal begins with ``owner``."""

    def resolve(self, options: dict, model_files: Sequence[Any]) -> ResolvedPrior:
        """``options`` (every declared option, resolved) and ``model_files`` as the prior takes them."""


@dataclass(frozen=True)
class _Hooks:
    """A :class:`Composition` made of the two functions :func:`register_prior` took before there was one
    (``referenced_files`` and ``given_defaults``); it names no option and relocates nothing."""

    referenced_files: Callable[[dict], Sequence[Path]] | None = None
    given_defaults: Callable[[dict, Sequence[Any]], tuple[dict, Sequence[Any]]] | None = None
    option: str = ""

    def written(self, components: Sequence[GivenComponent]) -> str:
        raise InputError("this prior takes no components as tables")

    def located(self, value: str, path: Callable[[str], str], owner: str) -> str:
        return value

    def resolve(self, options: dict, model_files: Sequence[Any]) -> ResolvedPrior:
        if self.given_defaults is not None:
            options, model_files = self.given_defaults(options, model_files)
        named = () if self.referenced_files is None else tuple(Path(f) for f in self.referenced_files(options))
        return ResolvedPrior(options, tuple(model_files), named)


@dataclass(frozen=True)
class PriorEntry:
    name: str
    build: Callable[[PriorContext, Sequence[Path], dict], Any]
    summary: str = ""
    options: tuple[Option, ...] = ()
    model_files: str = "none"  # "none", "one", "several" or "any" (the builder checks the count)
    train: Callable[..., Any] | None = None
    train_options: tuple[Option, ...] = ()
    resumable: bool = False
    #: For a prior made of other registered priors (a mixture): how its option names them, the model files
    #: those name, and what it takes when given no model file (:class:`Composition`); None for any other prior.
    composition: Composition | None = None

    @property
    def owner(self) -> str:
        """How messages name the prior: ``prior crbm``."""
        return f"prior {self.name}"

    def check_model_files(self, count: int, owner: str | None = None, needs: str = "a model file") -> None:
        """Refuse ``count`` model files where the prior takes another number (:attr:`model_files`: none, one,
        at least one; ``"any"``: its builder checks). Each refusal is one line beginning with ``owner`` (default
        ``prior NAME``); ``needs`` says how a missing model file is given (``models = [...] or train = [...]``)."""
        owner = owner or self.owner
        if self.model_files == "none" and count:
            raise InputError(f"{owner} takes no model files")
        if self.model_files in ("one", "several") and not count:
            raise InputError(f"{owner} needs {needs}")
        if self.model_files == "one" and count > 1:
            raise InputError(f"{owner} takes one model file, got {count}")

    def resolve(self, options: Mapping[str, Any], model_files: Sequence[Any] = ()) -> ResolvedPrior:
        """The prior's declared options from ``options`` (checked) or their defaults, and its model files,
        completed by its :attr:`composition` where it has one (what it takes when given none, the files its
        options name): what its builder is called with and what a run records."""
        resolved = resolve_options(self.owner, self.options, options)
        if self.composition is None:
            return ResolvedPrior(resolved, tuple(model_files))
        return self.composition.resolve(resolved, model_files)

    def located(self, options: dict, path: Callable[[str], str], owner: str | None = None) -> dict:
        """``options`` with each model file that they name (a mixture's ``model=FILE``) replaced by
        ``path(file)``, e.g. made absolute so that they mean the same files from any folder; ``options`` itself
        when they name none."""
        value = None if self.composition is None else options.get(self.composition.option)
        if not isinstance(value, str):
            return options
        located = self.composition.located(value, path, owner or self.owner)
        return options if located == value else {**options, self.composition.option: located}

    def complete(self, options: dict, model_files: Sequence[Any]) -> tuple[dict, list[Any]]:
        """``(options, model_files)`` as :meth:`resolve` completes them, for options already resolved."""
        if self.composition is None:
            return options, list(model_files)
        resolved = self.composition.resolve(options, model_files)
        return resolved.options, list(resolved.model_files)

    @property
    def referenced_files(self) -> Callable[[dict], list[Path]] | None:
        """The model files that resolved options name (``referenced_files(options) -> [path, ...]``); None for a
        prior whose options name none. :meth:`resolve` gives them as :attr:`ResolvedPrior.named_files`."""
        if self.composition is None:
            return None
        # with a model file given, resolve adds no default: the files are those the options name as they are
        return lambda options: list(self.composition.resolve(options, (None,)).named_files)


@dataclass(frozen=True)
class LikelihoodEntry:
    name: str
    build: Callable[[LikelihoodContext, dict], Any]
    summary: str = ""
    options: tuple[Option, ...] = ()


E = TypeVar("E")


def _origin(build: Callable) -> str:
    """Where a builder is defined (module and name): re-importing the same module registers the same one."""
    return f"{getattr(build, '__module__', '?')}.{getattr(build, '__qualname__', '?')}"


@dataclass
class Registry(Generic[E]):
    """Entries by name; a name registers once (re-registering the same function, as a re-import does, is fine).

    ``key`` is the attribute of an entry that names it and ``function`` the attribute holding the function whose
    origin (module and name) tells a re-registration from a second function taking a taken name. ``taken`` is
    the refusal of the latter, formatted with ``kind``, ``key``, ``old`` and ``new`` (the two functions' origins)
    and ``entry`` (the registered entry). The plugin tables key builders by name; the mocap readers
    (:mod:`data_tools.motion.readers`) key read functions by file suffix.
    """

    kind: str
    entries: dict[str, E] = field(default_factory=dict)
    key: str = "name"
    function: str = "build"
    taken: str = "a {kind} named {key!r} is already registered by {old}; {new} cannot take the name"
    #: What fills the registry before its first lookup: the application sets the one function that imports the
    #: plugins (:func:`tracker.app.plugins.load_plugins`), so that no caller has to remember to.
    fill: Callable[[], None] | None = None
    _filling: bool = field(default=False, repr=False)

    def _filled(self) -> None:
        if self.fill is not None and not self._filling:
            self._filling = True
            try:
                self.fill()
            finally:
                self._filling = False

    def add(self, entry: E) -> E:
        key = getattr(entry, self.key)
        old = self.entries.get(key)
        if old is not None:
            before, after = _origin(getattr(old, self.function)), _origin(getattr(entry, self.function))
            if before != after:
                raise InputError(self.taken.format(kind=self.kind, key=key, old=before, new=after, entry=old))
        self.entries[key] = entry
        return entry

    def get(self, name: str) -> E:
        self._filled()
        if name not in self.entries:
            raise InputError(f"unknown {self.kind} {name!r}; available: {', '.join(self.names())}")
        return self.entries[name]

    def find(self, name: str) -> E | None:
        """The entry registered as ``name``, None when there is none."""
        self._filled()
        return self.entries.get(name)

    def names(self) -> list[str]:
        self._filled()
        return list(self.entries)

    def __contains__(self, name: object) -> bool:
        self._filled()
        return name in self.entries

    def __getitem__(self, name: str) -> E:
        """The entry registered as ``name`` (a ``KeyError`` where there is none, as a dict's)."""
        self._filled()
        return self.entries[name]

    def __len__(self) -> int:
        self._filled()
        return len(self.entries)

    def values(self) -> list[E]:
        """Every entry, in the order they registered."""
        self._filled()
        return list(self.entries.values())


PRIORS: Registry[PriorEntry] = Registry("prior")
LIKELIHOODS: Registry[LikelihoodEntry] = Registry("likelihood")


def register_prior(name: str, *, summary: str = "", options: Sequence[Option] = (), model_files: str = "none",
                   train: Callable[..., Any] | None = None, train_options: Sequence[Option] = (),
                   resumable: bool = False, composition: Composition | None = None,
                   referenced_files: Callable[[dict], Sequence[Path]] | None = None,
                   given_defaults: Callable[[dict, Sequence[Any]], tuple[dict, Sequence[Any]]] | None = None):
    """Decorator registering ``build(context, model_files, options) -> MotionPrior`` under ``name``.

    ``model_files`` says whether the prior takes none, ``"one"`` or ``"several"`` model files, or ``"any"``
    number that its builder checks (a mixture: one per learned component); ``train``
    (learned priors) is ``train(data: TrainingData, options, rng, progress, checkpoint) -> model`` with
    ``model.save(path)`` and ``model.summary()``, configured by ``train_options``; a ``resumable`` one also
    takes ``resume=True`` to continue from ``checkpoint``; ``composition`` is for a prior made of other
    registered priors (:class:`Composition`). ``referenced_files(options)`` (the model files the options name)
    and ``given_defaults(options, model_files)`` (what the prior takes when given none) are the former form of
    a composition's :meth:`~Composition.resolve`, still taken, with a :class:`DeprecationWarning`.
    """
    if model_files not in ("none", "one", "several", "any"):
        raise ValueError(f"model_files must be 'none', 'one', 'several' or 'any', got {model_files!r}")
    if referenced_files is not None or given_defaults is not None:
        if composition is not None:
            raise ValueError("give a composition, or referenced_files and given_defaults, not both")
        import warnings

        warnings.warn("register_prior's referenced_files and given_defaults are deprecated: give a composition "
                      "(tracker.engine.registry.Composition) whose resolve() does both", DeprecationWarning,
                      stacklevel=2)
        composition = _Hooks(referenced_files, given_defaults)

    def decorate(build):
        PRIORS.add(PriorEntry(name, build, summary, tuple(options), model_files, train, tuple(train_options),
                              resumable, composition))
        return build
    return decorate


def register_likelihood(name: str, *, summary: str = "", options: Sequence[Option] = ()):
    """Decorator registering ``build(context, options) -> Likelihood`` under ``name``."""
    def decorate(build):
        LIKELIHOODS.add(LikelihoodEntry(name, build, summary, tuple(options)))
        return build
    return decorate

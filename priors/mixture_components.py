"""The mixture's ``components`` option: how a mixture names the registered priors it mixes, in the compact form
``PRIOR[:key=value...]``, comma-separated (``crbm:model=crbm1.pt:gibbs_steps=10,zero-velocity``), and how those
are checked against the registry.

A component names its registered ``prior``; ``model=FILE`` (repeatable) its own model file(s); ``models=N`` how
many of the mixture's model files it takes, in order (default: one for a learned prior, none otherwise,
:func:`default_model_files`); any other key one of its prior's options, written as on the command line. A value
holding ``,``, ``:`` or ``=`` is written in double quotes. The command line, the API and experiment files (whose
``[[prior.components]]`` tables are written into this form, :func:`written_components`) share it; the mixture's
registry entry carries it to them (:class:`~tracker.engine.registry.Composition`, :mod:`priors.mixture`).
"""
from __future__ import annotations

from dataclasses import dataclass, replace
from pathlib import Path
from typing import Any, Callable, Sequence

from tracker.core.errors import InputError
from tracker.engine.registry import PRIORS, GivenComponent, PriorEntry, resolve_options


@dataclass(frozen=True)
class Component:
    """One motion model of a mixture, as the ``components`` option writes it: its registered ``prior``, the
    model files it names itself (``model=FILE``, repeatable), how many of the mixture's own model files it takes
    in order when it names none (``models=N``; default one for a learned prior, none otherwise), and its options
    as written (``key=value``), checked and defaulted by :func:`component_options`."""

    prior: str
    models: tuple[str, ...] = ()
    takes: int | None = None
    options: tuple[tuple[str, str], ...] = ()

    def written(self) -> str:
        """The component in the option's form (:func:`parse_components` reads it back)."""
        keys = [("model", m) for m in self.models] + ([] if self.takes is None else [("models", str(self.takes))])
        return ":".join([self.prior] + [f"{k}={_quoted(v)}" for k, v in keys + list(self.options)])


#: Characters that a value in the ``components`` option must be written in double quotes to contain.
_SEPARATORS = ",:="


def written_value(value: Any) -> str:
    """An option's value (from an experiment file's table) as the ``components`` option writes it."""
    if isinstance(value, bool):
        return "true" if value else "false"
    if isinstance(value, (int, float, str)):
        return repr(value) if isinstance(value, float) else str(value)
    raise InputError(f"a component's option must be a number, text or true/false, got {value!r}")


def _quoted(value: str) -> str:
    if '"' in value:
        raise InputError(f"a value in a mixture's components cannot contain a double quote, got {value!r}")
    return f'"{value}"' if any(c in value for c in _SEPARATORS) or value != value.strip() else value


def _split(text: str, separator: str) -> list[str]:
    """``text`` split at ``separator`` outside double quotes (the quotes kept)."""
    parts, current, quoted = [], [], False
    for c in text:
        if c == '"':
            quoted = not quoted
        if c == separator and not quoted:
            parts.append("".join(current))
            current = []
        else:
            current.append(c)
    if quoted:
        raise ValueError("a double quote is not closed")
    return parts + ["".join(current)]


def parse_components(value: str, owner: str) -> list[Component]:
    """The components of ``value``: ``PRIOR[:key=value...]`` separated by commas (``crbm:model=crbm1.pt:
    gibbs_steps=10,zero-velocity``; a value holding ``,``, ``:`` or ``=`` in double quotes). Only the form is
    checked here (:func:`check_components` checks the priors and options)."""
    def refuse(reason: str) -> InputError:
        return InputError(f"{owner}: components {reason}, e.g. crbm,zero-velocity or "
                          f"crbm:model=crbm1.pt:gibbs_steps=10,zero-velocity; got {value!r}")

    try:
        written = [_split(c, ":") for c in _split(value, ",")]
    except ValueError as exc:
        raise refuse(f"are not readable ({exc})") from None
    out = []
    for k, (name, *pairs) in enumerate(written):
        name = name.strip()
        if not name:
            raise refuse("must name two or more priors, comma-separated")
        models, takes, options = [], None, []
        for pair in pairs:
            key, sep, v = pair.partition("=")
            key, v = key.strip(), v.strip()
            if not sep or not key:
                raise refuse(f"give each setting of a component as key=value (component {k + 1}: {pair!r})")
            v = v[1:-1] if len(v) >= 2 and v[0] == v[-1] == '"' else v
            if key == "model":
                if not v:
                    raise refuse(f"name a file in model=FILE (component {k + 1})")
                models.append(v)
            elif key == "models":
                if not v.isdigit():
                    raise refuse(f"take models=N, a number of the mixture's model files (component {k + 1})")
                takes = int(v)
            else:
                options.append((key, v))
        if models and takes is not None:
            raise refuse(f"give a component model=FILE or models=N, not both (component {k + 1})")
        out.append(Component(name, tuple(models), takes, tuple(options)))
    if len(out) < 2:
        raise refuse("must name two or more priors, comma-separated")
    return out


def with_model_paths(value: str, owner: str, path: Callable[[str], str]) -> str:
    """``value`` (the ``components`` option) with each component's ``model=FILE`` replaced by ``path(FILE)``
    (e.g. made absolute, so that the option means the same files from any folder); ``value`` itself when no
    component names a model file."""
    components = parse_components(value, owner)
    if not any(c.models for c in components):
        return value
    return ",".join(replace(c, models=tuple(path(m) for m in c.models)).written() for c in components)


def written_components(components: Sequence[GivenComponent]) -> str:
    """The option's value for components given as tables (an experiment file's ``[[prior.components]]``): each
    written with its options, and with ``models=N`` where it takes another count of the mixture's model files
    than its default; no path enters the value (the files are the mixture's own, in order)."""
    written = []
    for k, c in enumerate(components):
        try:
            values = tuple((key, written_value(v)) for key, v in c.options.items())
        except InputError as exc:
            raise InputError(f"component {k + 1} ({c.prior}): {exc.reason}") from None
        takes = None if c.model_files == default_model_files(PRIORS.get(c.prior)) else c.model_files
        written.append(Component(c.prior, (), takes, values).written())
    return ",".join(written)


# -- checked against the registry ---------------------------------------------------------------------------------

def default_model_files(entry: PriorEntry) -> int:
    """How many of the mixture's model files a component of ``entry``'s prior takes when it says nothing: one
    for a learned prior, none otherwise."""
    return int(entry.model_files != "none")


def component_options(component: Component, index: int, owner: str) -> dict:
    """Every option of ``component``'s prior, from those it writes (checked) or the default."""
    entry = PRIORS.get(component.prior)
    written = dict(component.options)
    if len(written) != len(component.options):
        raise InputError(f"{owner}: component {index + 1} ({component.prior}) gives an option twice")
    return resolve_options(f"{owner}: component {index + 1} ({component.prior})", entry.options, written)


def model_files_taken(components: Sequence[Component], takes: Sequence[int]) -> str:
    """How many of a mixture's model files its components take, and which (``takes 2 model files (crbm: 2)``;
    ``takes no model files``): ``takes[k]`` is component ``k``'s count."""
    total = sum(takes)
    if not total:
        return "takes no model files"
    each = ", ".join(f"{c.prior}: {n}" for c, n in zip(components, takes) if n)
    return f"takes {total} model file{'s' if total != 1 else ''} ({each})"


def check_components(value: str, owner: str) -> None:
    """The ``components`` option: its form, registered priors (no mixture), each component's options, and model
    files only for learned priors (a component that names none takes the mixture's)."""
    for k, c in enumerate(parse_components(value, owner)):
        if c.prior == "mixture":
            raise InputError(f"{owner}: a mixture cannot be a component of a mixture")
        count = len(c.models) or (c.takes or 0)
        if count:
            PRIORS.get(c.prior).check_model_files(count, f"{owner}: component {k + 1} ({c.prior})")
        component_options(c, k, owner)


def component_files(value: str, owner: str = "prior mixture") -> list[Path]:
    """The model files that the ``components`` option ``value`` names (``model=FILE``), in order."""
    return [Path(m) for c in parse_components(value, owner) for m in c.models]

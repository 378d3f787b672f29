"""How a prior made of other priors (a mixture) names its components in one option: the compact form
``PRIOR[:key=value...]``, comma-separated (``crbm:model=crbm1.pt:gibbs_steps=10,zero-velocity``).

A component names its registered ``prior``; ``model=FILE`` (repeatable) its own model file(s); ``models=N`` how
many of the composite prior's model files it takes, in order (default: one for a learned prior, none otherwise);
any other key one of its prior's options, written as on the command line. A value holding ``,``, ``:`` or ``=`` is
written in double quotes. Only the form is read here: the prior that has components checks the names and options
against the registry (:func:`priors.mixture.check_components`). The command line, the API and experiment files
(whose ``[[prior.components]]`` tables are written into this form) share it.
"""
from __future__ import annotations

from dataclasses import dataclass, replace
from typing import Any, Callable

from tracker.core.errors import InputError


@dataclass(frozen=True)
class Component:
    """One motion model of a mixture, as the ``components`` option writes it: its registered ``prior``, the
    model files it names itself (``model=FILE``, repeatable), how many of the mixture's own model files it takes
    in order when it names none (``models=N``; default one for a learned prior, none otherwise), and its options
    as written (``key=value``), checked and defaulted by :func:`priors.mixture.component_options`."""

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

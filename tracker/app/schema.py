"""The settings of a tracking run, declared once: the schema that the command line, the API, experiment files,
``result.json`` and the checkpoint's fingerprint derive from.

A run's settings are the filter's (:data:`tracker.engine.config.FILTER_OPTIONS`: particles, annealing, resampling)
and the run's own (:data:`RUN_OPTIONS`: known frames, frames, views, seed, device, checkpoints), each an
:class:`~tracker.engine.registry.Option` with its type, default, bounds, unit and help. The prior and the
likelihood bring their own options from the registries (``pose-tracker track --prior NAME --help``), a mixture's
components each theirs (:mod:`priors.mixture`). Where each setting appears:

- ``pose-tracker track``: one flag per setting of :data:`TRACK_SETTINGS` (``--annealing-layers``), its help the
  option's, its value checked by the option (:func:`add_flags`);
- ``tracker.track``: one keyword per setting, named and defaulted as here;
- an experiment file's ``[tracking]`` table: the settings of :data:`EXPERIMENT_SETTINGS` (an experiment draws its
  seeds from its own ``seed`` and runs on the CPU), those of :data:`GRID_AXES` a value or a list of values;
- ``result.json`` and the checkpoint's fingerprint: a key per setting of :data:`RECORDED_SETTINGS`, its value as
  the run resolved it (``views``: the camera indices tracked, ``frames``: the frames covered).

Units belong to the schema (``Option.unit``), not to the keys.
"""
from __future__ import annotations

import argparse
from typing import Any, Mapping, Sequence

from tracker.core.errors import InputError
from tracker.engine.config import FILTER_OPTIONS, MAX_PARTICLES, TRACK_ANNEALING_LAYERS
from tracker.engine.registry import Option

__all__ = ["FILTER_OPTIONS", "MAX_PARTICLES", "TRACK_ANNEALING_LAYERS", "KEYPOINT_LIKELIHOOD", "SILHOUETTE_LIKELIHOOD",
           "RUN_OPTIONS", "TRACK_SETTINGS", "EXPERIMENT_SETTINGS", "GRID_AXES", "RECORDED_SETTINGS", "setting",
           "defaults", "check", "add_flags", "add_option_flags"]

#: The largest seed (numpy's generators take any non-negative integer; results name it as an int64).
MAX_SEED = 2 ** 63 - 1

RUN_OPTIONS: tuple[Option, ...] = (
    Option("known_frames", int, 2, "known frames the filter starts from, as in Taylor 2009", minimum=1,
           unit="frames"),
    Option("frames", int, None, "track frames 0..N-1 (default: the whole sequence)", minimum=1, unit="frames"),
    Option("views", int, None, "camera indices, comma-separated on the command line (default: all)", minimum=0,
           many=True),
    Option("seed", int, 0, "random seed", minimum=0, maximum=MAX_SEED),
    Option("device", str, "cpu", "where particles are scored: cpu (the compiled CPU path) or cuda, cuda:N (the GPU "
           "path: the likelihood's kinematics, projection and image lookups, and a learned prior's torch "
           "sampling)"),
    Option("checkpoint_every", int, 25, "save the filter's state every K frames to the checkpoint (0: only on "
           "Ctrl-C); removed once the results are written", minimum=0, unit="frames"),
)

#: The likelihood a run takes unless told (:func:`tracker.app.api.default_likelihood`), for a sequence with 2-D
#: keypoints and for one without; a command line that names no likelihood takes the options of both.
KEYPOINT_LIKELIHOOD, SILHOUETTE_LIKELIHOOD = "keypoints+edge-silhouette", "edge-silhouette"

#: Every setting of a run, by name.
TRACK_SETTINGS: dict[str, Option] = {o.name: o for o in FILTER_OPTIONS + RUN_OPTIONS}
#: The settings an experiment file's ``[tracking]`` table takes.
EXPERIMENT_SETTINGS: tuple[str, ...] = tuple(o.name for o in FILTER_OPTIONS) + ("known_frames", "frames", "views")
#: The ``[tracking]`` settings whose value may be a list of values, one configuration each (``views``: a list of
#: view sets).
GRID_AXES: tuple[str, ...] = ("particles", "annealing_layers", "views")
#: The settings ``result.json`` records (and a resumed run must match); checkpoints do not change a run's numbers.
RECORDED_SETTINGS: tuple[str, ...] = tuple(n for n in TRACK_SETTINGS if n != "checkpoint_every")


def setting(name: str) -> Option:
    """The declared setting ``name``."""
    return TRACK_SETTINGS[name]


def defaults(names: Sequence[str] | None = None) -> dict[str, Any]:
    """The defaults of the settings ``names`` (default all)."""
    return {n: TRACK_SETTINGS[n].default for n in (TRACK_SETTINGS if names is None else names)}


def check(values: Mapping[str, Any], owner: str) -> dict[str, Any]:
    """``values`` (setting name -> value) checked against their options; an unknown name, or a value that breaks
    its option's rule, is one :class:`InputError` naming ``owner`` and the setting."""
    unknown = sorted(set(values) - set(TRACK_SETTINGS))
    if unknown:
        raise InputError(f"{owner} has no setting {', '.join(map(repr, unknown))} (its settings: "
                         f"{', '.join(TRACK_SETTINGS)})")
    return {n: TRACK_SETTINGS[n].parse(v, owner) for n, v in values.items()}


# -- the command line -------------------------------------------------------------------------------------------

def argument_type(option: Option):
    """An argparse type for ``option``: the option's conversion and rule, the message in argparse's form
    (``expected an integer, got 'x'``; ``must be at least 1 and at most 1000000, got 0``)."""
    nouns = {int: "an integer", float: "a number"}

    def parse(text: str):
        value: Any = text
        if not option.many and option.type in nouns:
            try:
                value = option.type(text)
            except ValueError:
                raise argparse.ArgumentTypeError(f"expected {nouns[option.type]}, got {text!r}") from None
        try:
            return option.parse(value, option.flag)
        except InputError as exc:
            reason = exc.reason.split(": ", 1)[-1]
            raise argparse.ArgumentTypeError(reason.removeprefix(option.name + " ")) from None

    parse.__name__ = option.name  # argparse names the type in its messages
    return parse


_METAVARS = {"checkpoint_every": "K", "device": "DEVICE"}


def add_flags(parser: argparse.ArgumentParser | Any, names: Sequence[str]) -> None:
    """One flag per setting of ``names`` (``--known-frames``), its default, help and check the option's."""
    add_option_flags(parser, [TRACK_SETTINGS[name] for name in names], _METAVARS)


def add_option_flags(parser: argparse.ArgumentParser | Any, options: Sequence[Option],
                     metavars: Mapping[str, str] = {}) -> None:
    """One flag per option (``--lighting-change``; a bool option a switch that turns it on), its default, help
    and check the option's; ``metavars`` names some options' values in the help."""
    for o in options:
        kwargs: dict[str, Any] = {"dest": o.name, "default": o.default, "help": o.described()}
        if o.type is bool:
            kwargs["action"] = "store_true"
            parser.add_argument(o.flag, **kwargs)
            continue
        if o.choices:
            kwargs["choices"] = list(o.choices)
        elif not o.many:  # a list is kept as written: the command checks it against the sequence (its cameras)
            kwargs["type"] = argument_type(o)
        if o.name in metavars:
            kwargs["metavar"] = metavars[o.name]
        parser.add_argument(o.flag, **kwargs)

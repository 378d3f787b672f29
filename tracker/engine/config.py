"""The particle filter's settings, declared once as typed options, and :class:`FilterConfig`, the filter's
configuration, derived from them.

Each setting of :data:`FILTER_OPTIONS` has its type, default, bounds, unit and help here and nowhere else: the
command line's flags, the API's keywords, an experiment file's ``[tracking]`` keys and the keys of
``result.json`` are the option names (:mod:`tracker.app.schema` adds the settings of a run that are not the
filter's).

One default differs between the engine and a run: a run (``tracker.track``, ``pose-tracker track``, an
experiment) anneals with :data:`TRACK_ANNEALING_LAYERS` layers per frame, the option's default, while a
:class:`FilterConfig` built in code without ``annealing_layers`` is plain SIR (:data:`ENGINE_ANNEALING_LAYERS`),
the engine's textbook filter that its tests and benchmarks measure.
"""
from __future__ import annotations

from dataclasses import dataclass, fields
from typing import Any, Mapping

from tracker.core.errors import InputError
from tracker.engine.registry import Option
from tracker.engine.resampling import SCHEMES

#: The most particles a run may ask for: far beyond any run (Taylor 2009 uses 200-1000), and a million
#: particles already take gigabytes per frame.
MAX_PARTICLES = 1_000_000
#: The most annealing layers per frame (Deutscher & Reid use 10).
MAX_ANNEALING_LAYERS = 100
#: Annealing layers per frame of a run when none are asked for: 3 won in ``docs/methods_report.md`` ("the
#: annealed filter") for the zero-velocity baseline and the paced CRBM on people the priors were not trained on,
#: and the FCRBM's tuning fold with its style inferred by mixture tracking.
TRACK_ANNEALING_LAYERS = 3
#: :class:`FilterConfig`'s own default: plain SIR (see the module docstring).
ENGINE_ANNEALING_LAYERS = 1

FILTER_OPTIONS: tuple[Option, ...] = (
    Option("particles", int, 1000, "number of particles", minimum=1, maximum=MAX_PARTICLES),
    Option("annealing_layers", int, TRACK_ANNEALING_LAYERS, "annealed layers per frame; 1 is plain SIR",
           minimum=1, maximum=MAX_ANNEALING_LAYERS),
    Option("resampling", str, "systematic", "resampling scheme", choices=tuple(SCHEMES)),
    Option("ess_threshold", float, 0.5, "resample when the effective sample size falls below this fraction of "
           "the particles (an annealed frame always resamples)", minimum=0.0, maximum=1.0),
    Option("survival_rate", float, 0.5, "annealing: the fraction of the particles each layer's sharpening "
           "exponent keeps, as effective sample size", minimum=0.0, strict=True, maximum=1.0, strict_max=True),
    Option("layer_diffusion_decay", float, 0.5, "annealing: each layer's diffusion is the previous layer's "
           "times this", minimum=0.0, strict=True, maximum=1.0),
)
_BY_NAME = {o.name: o for o in FILTER_OPTIONS}
#: The :class:`FilterConfig` field of an option whose field name predates the options (``n_particles``).
_FIELD = {"particles": "n_particles"}


@dataclass(frozen=True)
class FilterConfig:
    """Particle count, resampling scheme and ESS trigger, and the annealing options (layers per frame, target
    survival rate, diffusion decay per layer): the values of :data:`FILTER_OPTIONS` (``n_particles`` is the
    option ``particles``), defaults included, except ``annealing_layers`` (module docstring)."""

    n_particles: int = _BY_NAME["particles"].default
    resampling: str = _BY_NAME["resampling"].default
    ess_threshold: float = _BY_NAME["ess_threshold"].default
    annealing_layers: int = ENGINE_ANNEALING_LAYERS
    survival_rate: float = _BY_NAME["survival_rate"].default
    layer_diffusion_decay: float = _BY_NAME["layer_diffusion_decay"].default

    @classmethod
    def from_options(cls, values: Mapping[str, Any]) -> "FilterConfig":
        """The configuration of option values by option name (those not given take the options' defaults, a
        run's), checked."""
        unknown = sorted(set(values) - set(_BY_NAME))
        if unknown:
            raise InputError(f"the filter has no setting {', '.join(map(repr, unknown))} (its settings: "
                             f"{', '.join(_BY_NAME)})")
        merged = {o.name: values.get(o.name, o.default) for o in FILTER_OPTIONS}
        return cls(**{_FIELD.get(k, k): v for k, v in merged.items()}).check()

    def options(self) -> dict[str, Any]:
        """The settings by option name (what ``result.json`` records)."""
        return {o.name: getattr(self, _FIELD.get(o.name, o.name)) for o in FILTER_OPTIONS}

    def check(self) -> "FilterConfig":
        """Every value checked against its option (one :class:`InputError` stating the rule)."""
        values = {f.name: getattr(self, f.name) for f in fields(self)}
        for o in FILTER_OPTIONS:
            field_name = _FIELD.get(o.name, o.name)
            value = values[field_name]
            checked = o.parse(int(value) if o.type is int and hasattr(value, "__index__") else value, "filter")
            object.__setattr__(self, field_name, checked)
        return self

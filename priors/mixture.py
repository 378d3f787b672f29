"""A mixture of motion models, weighed by their evidence: a learned prior that falls back on another.

(This module is the prior and its registration; how its ``components`` option is written and checked is
:mod:`priors.mixture_components`, the filter's mechanism of components kept apart is
:mod:`tracker.engine.multiple_models`, and the way the particles are split among the models is
:class:`priors.ensemble.Composite`'s.)

A learned prior is only as good as its training motion: on motion it never saw it pulls every particle toward
what it knows, and no single particle can escape. The mixture gives each of several priors (for example a
learned prior and zero-velocity, or a walk-trained and an all-activity model) a fixed share of the particles.
The filter keeps the shares apart and weighs each by its evidence, the mean likelihood of its own samples
tempered by ``temperature`` (mixture tracking, :mod:`tracker.engine.multiple_models`); every frame each share is redrawn
from all particles, a particle's component changing with probability ``switch`` in the transition of the IMM
mixing step, so a component that loses its weight is refilled from the winner's particles and takes over again
when its motion returns.
A model that keeps components of its own (a :class:`~tracker.engine.multiple_models.ComponentPrior`, such as an FCRBM
inferring its style label) takes part with each of its components (they then switch among themselves as it
says, but are weighed with the mixture's ``temperature``, not its own). The estimate is the mixture's posterior
mean; the per-frame summary is the posterior over the components.

A particle that switches component brings its own history; the new component derives the state it keeps per
particle from it (:func:`~tracker.engine.prior.adopt`: the step out of the newest pose, GPDM latent
coordinates) on the next frame, and keeps the slow quantities (a pace, a height offset) its share had.

State (:class:`~priors.ensemble.Composite`'s): ``component`` ``(P,)`` (fixed per particle position: contiguous
blocks of equal size), ``arrived`` ``(P,)`` and ``model_k`` the state of component ``k``.
"""
from __future__ import annotations

from pathlib import Path
from typing import Any, Callable, Sequence

import numpy as np

from priors.ensemble import Composite
from tracker.core.errors import InputError
from priors.mixture_components import (check_components, component_files, component_options, default_model_files,
                                       model_files_taken, parse_components, with_model_paths, written_components)
from tracker.engine.multiple_models import Mixing, mixing_of
from tracker.engine.prior import MotionPrior, PriorState, label_for, reindex_state, restart
from tracker.engine.registry import PRIORS, GivenComponent, Option, PriorContext, ResolvedPrior, register_prior

#: Probability per frame that a particle's component changes, in the IMM mixing step's transition.
SWITCH = 0.05
#: The likelihood is raised to ``1 / TEMPERATURE`` when the components are weighed (as the FCRBM's styles are).
TEMPERATURE = 10.0
#: The switching probability and the evidence temperature, declared once: the command line, experiment files and
#: :class:`MixturePrior` all check them through these.
SWITCH_OPTION = Option("switch", float, SWITCH, "probability per frame that a particle's component changes (the "
                       "transition of the IMM mixing step)", minimum=0.0, maximum=0.5)
TEMPERATURE_OPTION = Option("evidence_temperature", float, TEMPERATURE, "the likelihood is raised to 1/T when the "
                            "components are weighed against each other", minimum=1.0, maximum=1000.0)


class MixturePrior(Composite):
    """Motion models each drawing a fixed share of the particles, weighed by their evidence (module docstring).

    ``components``: the priors; ``labels``: their names in the summary (default: their names, numbered where
    one repeats); ``switch``: the probability per frame that a particle's component changes (the IMM
    transition); ``temperature``: the evidence's temperature; both within their options' bounds
    (:data:`SWITCH_OPTION`, :data:`TEMPERATURE_OPTION`). The filter keeps the components apart
    (:class:`~tracker.engine.multiple_models.ComponentPrior`).
    """

    summary_kind = "posterior"

    def __init__(self, components: Sequence[MotionPrior], labels: Sequence[str] | None = None, *,
                 switch: float = SWITCH, temperature: float = TEMPERATURE):
        components = list(components)
        if len(components) < 2:
            raise InputError(f"a mixture needs at least two motion models, got {len(components)}")
        switch, temperature = SWITCH_OPTION.parse(switch, "mixture"), TEMPERATURE_OPTION.parse(temperature, "mixture")
        super().__init__(components)
        self.switch, self.temperature = switch, temperature
        self.labels = tuple(labels) if labels is not None else numbered([c.name for c in components])
        if len(self.labels) != len(components) or len(set(self.labels)) != len(components):
            raise InputError(f"a mixture needs one distinct label per component, got {list(self.labels)}")
        self.inner = [mixing_of(c) for c in components]  # the components' own components, where kept apart
        sizes = [1 if m is None else m.transition.shape[0] for m in self.inner]
        #: How many filter components each model takes, and the first of them ``(C,)``.
        self.sizes, self.first = sizes, np.concatenate([[0], np.cumsum(sizes)[:-1]]).astype(np.int64)
        self.summary_names = tuple(n for label, inner in zip(self.labels, self.inner) for n in
                                   ([label] if inner is None else [f"{label} {s}" for s in inner.names]))
        self.name = "mixture of " + " + ".join(self.labels)

    def layout(self, n_particles: int) -> np.ndarray:
        """Each position's component ``(P,)``: contiguous blocks of (nearly) equal size."""
        C = len(self.components)
        if n_particles < C:
            raise InputError(f"a mixture of {C} motion models needs at least {C} particles, got {n_particles}")
        return np.arange(n_particles) * C // n_particles

    def restart(self, state: PriorState, recent: np.ndarray, n_particles: int,
                rng: np.random.Generator) -> PriorState:
        """Every component restarted from ``recent``, each seeing only rows of its own block (a component's rows
        at the other blocks' positions are never updated: a restart that reads a particle's quantity, such as a
        posture offset or a clock, must not read those)."""
        new: dict = {"component": state["component"], "arrived": np.zeros(n_particles, bool)}
        for c, prior in enumerate(self.components):
            first = np.flatnonzero(state["component"] == c)[0]
            own = reindex_state(state[f"model_{c}"], np.full(n_particles, first))
            new[f"model_{c}"] = restart(prior, own, recent, n_particles, rng)
        return new

    def reindex(self, state: PriorState, idx: np.ndarray) -> PriorState:
        """After resampling picked particles ``idx``: a position whose new particle came from its own component
        takes that particle's rows; one whose particle came from another component keeps the rows its component
        had there and is marked ``arrived`` (:meth:`sample` derives its pose-dependent state then)."""
        component = state["component"]
        crossed = component[idx] != component
        rows = np.where(crossed, np.arange(len(idx)), idx)
        new: dict = {"component": component, "arrived": np.where(crossed, True, state["arrived"][idx])}
        for c, prior in enumerate(self.components):
            new[f"model_{c}"] = prior.reindex(state[f"model_{c}"], rows)
        return new

    # -- components kept apart (tracker.engine.multiple_models.ComponentPrior) -------------------------------------

    def mixing(self) -> Mixing:
        """The filter's components: one per motion model, or, for a model that keeps components of its own (an
        FCRBM's style labels), one per model and component, those switching among themselves as the model
        says. Between models a particle switches with probability ``switch``, to each component of the other
        model alike. Named as :attr:`summary_names`."""
        sizes, start = self.sizes, self.first
        C = len(self.components)
        transition = np.zeros((sum(sizes), sum(sizes)))
        for a in range(C):
            for b in range(C):
                block = (1.0 - self.switch) * (np.ones((1, 1)) if self.inner[a] is None else
                                               self.inner[a].transition) \
                    if a == b else np.full((sizes[a], sizes[b]), self.switch / (C - 1) / sizes[b])
                transition[start[a]:start[a] + sizes[a], start[b]:start[b] + sizes[b]] = block
        return Mixing(self.summary_names, transition, self.temperature)

    def component_of(self, state: PriorState) -> np.ndarray:
        """Each particle's filter component ``(P,)``: its model's first, plus its own component in that model."""
        outer = state["component"]
        flat = self.first[outer]
        for a, prior in enumerate(self.components):
            if self.inner[a] is not None:
                in_block = outer == a
                flat[in_block] += np.asarray(prior.component_of(state[f"model_{a}"]))[in_block]
        return flat

    def relabel(self, state: PriorState, flat: np.ndarray) -> PriorState:
        """A model that keeps components of its own learns its particles' new ones from the filter's components
        ``flat`` ``(P,)`` (:meth:`mixing`'s numbering over models and their components)."""
        outer, new = state["component"], dict(state)
        for c, prior in enumerate(self.components):
            if self.inner[c] is not None:
                own = state[f"model_{c}"]
                labels = np.where(outer == c, flat - self.first[c], prior.component_of(own))
                new[f"model_{c}"] = prior.relabel(own, labels)
        return new

    # -- what it reports -----------------------------------------------------------------------------------------

    def diffusion_std(self) -> np.ndarray:
        """The root-mean-square of the components' one-step scales ``(D,)``."""
        return np.sqrt(np.mean([np.square(c.diffusion_std()) for c in self.components], axis=0))

    def summarize(self, state: PriorState, weights: np.ndarray) -> np.ndarray:
        """The posterior over :attr:`summary_names` under the normalised ``weights`` ``(P,)``: each model's
        particles' weights summed, split over its own components for a model that keeps components apart."""
        out = []
        for c, prior in enumerate(self.components):
            m = np.flatnonzero(state["component"] == c)
            total = float(weights[m].sum())
            if self.inner[c] is None:
                out.append([total])
                continue
            own = np.asarray(prior.component_of(state[f"model_{c}"]))[m]
            split = np.bincount(own, weights=weights[m], minlength=self.inner[c].transition.shape[0])
            out.append(split / split.sum() * total if split.sum() > 0 else np.full(len(split), total / len(split)))
        values = np.concatenate(out)
        return values / values.sum() if values.sum() > 0 else np.full(len(values), 1.0 / len(values))

    def settings(self) -> dict:
        return {"components": list(self.labels), "switch": self.switch, "evidence_temperature": self.temperature,
                "component_settings": {n: c.settings() for n, c in zip(self.labels, self.components)}}

    def label_for(self, available: int) -> str:
        return " + ".join(label_for(c, min(available, c.order)) for c in self.components)


def numbered(names: Sequence[str]) -> tuple[str, ...]:
    """``names`` with a repeated name numbered from its second occurrence on (``crbm``, ``crbm 2``)."""
    out, seen = [], {}
    for n in names:
        seen[n] = seen.get(n, 0) + 1
        out.append(n if seen[n] == 1 else f"{n} {seen[n]}")
    return tuple(out)


# ---------------------------------------------------------------------------
# Registration
# ---------------------------------------------------------------------------

#: The mixture's components by default; given no model file at all, the mixture is instead the package's
#: pretrained learned prior and zero-velocity (:mod:`priors.pretrained`).
DEFAULT_COMPONENTS = "crbm,zero-velocity"

MIXTURE_OPTIONS = (
    Option("components", str, DEFAULT_COMPONENTS,
           "the motion models mixed, comma-separated, each PRIOR[:key=value...]: model=FILE (repeatable) names "
           "a learned component's model file, models=N takes the next N of the mixture's model files (a learned "
           "component that names none takes the next one, in order), any other key is the component's own "
           "option (crbm:model=crbm1.pt:gibbs_steps=10,zero-velocity); unset options take their defaults. Given "
           "no model file, the default is the package's pretrained neural prior (trained on CMU motion capture) "
           "and zero-velocity",
           check=check_components),
    SWITCH_OPTION,
    TEMPERATURE_OPTION,
)


def pretrained_default(options: dict, model_files: Sequence[Any]) -> tuple[dict, Sequence[Any]]:
    """The mixture given no model file and its default components: the package's pretrained learned prior and
    zero-velocity (:mod:`priors.pretrained`), as options naming them and the shipped model file; anything else
    as given."""
    if model_files or options["components"] != DEFAULT_COMPONENTS:
        return options, model_files
    from priors.pretrained import MIXTURE_COMPONENTS, mixture_model

    return {**options, "components": MIXTURE_COMPONENTS}, [mixture_model()]


class MixtureComposition:
    """The mixture's entry in the registry, as a prior made of other priors
    (:class:`~tracker.engine.registry.Composition`): its ``components`` option
    (:mod:`priors.mixture_components`), and the pretrained default when given no model file."""

    option = "components"

    def written(self, components: Sequence[GivenComponent]) -> str:
        return written_components(components)

    def located(self, value: str, path: Callable[[str], str], owner: str) -> str:
        return with_model_paths(value, owner, path)

    def resolve(self, options: dict, model_files: Sequence[Any]) -> ResolvedPrior:
        options, model_files = pretrained_default(options, model_files)
        return ResolvedPrior(options, tuple(model_files), tuple(component_files(options["components"])))


@register_prior("mixture", summary="several motion models, each drawing a share of the particles, weighed by "
                                   "their evidence (a learned prior that falls back on zero-velocity)",
                options=MIXTURE_OPTIONS, model_files="any", composition=MixtureComposition())
def build_mixture(context: PriorContext, model_files: Sequence[Path], options: dict) -> MixturePrior:
    """The mixture of ``options["components"]``, each built by its own prior's builder with its own options and
    model files: those it names (``model=FILE``), else the next of ``model_files`` in order (``models=N`` of
    them; one for a learned component)."""
    owner = "prior mixture"
    components = parse_components(options["components"], owner)
    entries = [PRIORS.get(c.prior) for c in components]
    takes = [0 if c.models else (c.takes if c.takes is not None else default_model_files(e))
             for c, e in zip(components, entries)]
    if sum(takes) != len(model_files):
        names = ", ".join(c.prior for c in components)
        raise InputError(f"the mixture of {names} {model_files_taken(components, takes)}, got {len(model_files)}")
    files = iter(model_files)
    built, given_files = [], []
    for k, (c, e, n) in enumerate(zip(components, entries, takes)):
        given = [Path(m) for m in c.models] or [next(files) for _ in range(n)]
        e.check_model_files(len(given), f"{owner}: component {k + 1} ({c.prior})",
                            needs="a model file (model=FILE, or one of the mixture's model files)")
        built.append(e.build(context, given, component_options(c, k, owner)))
        given_files.append(given)
    labels = [c.prior for c in components]
    if len(set(labels)) < len(labels) and all(isinstance(f, (str, Path)) for g in given_files for f in g):
        # two models of one prior: told apart by their files
        labels = [f"{c.prior} ({Path(g[0]).stem})" if g else c.prior for c, g in zip(components, given_files)]
    return MixturePrior(built, numbered(labels), switch=options["switch"],
                        temperature=options["evidence_temperature"])

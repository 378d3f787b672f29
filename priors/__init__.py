"""Motion priors (zero/constant velocity, CRBM, FCRBM, deep CRBM, GPDM, mixtures). They import only the geometry core
and the engine's contracts in ``tracker``.

Each learned prior is a package of its own (``model``, ``training``, ``file`` and ``prior`` modules); the pieces they
share are modules of their own (:mod:`priors.parts`, :mod:`priors.conditional`, :mod:`priors.common`,
:mod:`priors.settings`, :mod:`priors.contrastive`).
"""

#: The modules that register the built-in priors, in the order the command line lists them:
#: :func:`tracker.app.plugins.load_plugins` imports these. A prior module imports its model (and torch) only when
#: its prior is built or trained, so listing the priors and their options is cheap.
BUILTIN_MODULES = ("priors.crbm.prior", "priors.deep_crbm.prior", "priors.fcrbm.prior", "priors.gpdm.prior",
                   "priors.neural.prior", "priors.mixture", "priors.random_walk")

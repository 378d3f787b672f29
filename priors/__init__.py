"""Motion priors (zero/constant velocity, CRBM, GPDM). They import only the geometry core in ``tracker``."""

#: The modules that register no prior (the models, their training and files, the shared parts and settings):
#: :func:`tracker.app.plugins.load_plugins` imports every other module of the package. A prior module imports
#: these (and torch) only when its prior is built or trained, so listing the priors and their options is cheap.
SUPPORT_MODULES = ("common", "conditional", "contrastive", "crbm_file", "crbm_model", "crbm_training", "ensemble",
                   "fcrbm_model", "gpdm_model", "gpdm_predict", "gpdm_training", "parts", "settings")

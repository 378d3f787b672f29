"""Image observations and the edge / silhouette likelihoods. They import only the geometry core in ``tracker``."""

#: The modules that register no likelihood (the observations and the compiled costs):
#: :func:`tracker.app.plugins.load_plugins` imports every other module of the package.
SUPPORT_MODULES = ("compiled_costs", "observations")

"""Image observations and the edge / silhouette likelihoods. They import only the geometry core in ``tracker``."""

#: The modules that register the built-in likelihoods: :func:`tracker.app.plugins.load_plugins` imports these.
BUILTIN_MODULES = ("likelihoods.edge_silhouette", "likelihoods.keypoints")

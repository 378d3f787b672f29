"""Image observations and the edge / silhouette likelihoods. They import only the geometry core in ``tracker``."""

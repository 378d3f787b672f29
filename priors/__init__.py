"""Motion priors (zero/constant velocity, CRBM, GPDM). They import only the geometry core in ``tracker``."""

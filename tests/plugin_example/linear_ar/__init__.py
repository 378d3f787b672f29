"""A learned prior as a plugin package writes one (docs/guide/extending.md, "Add a learned prior"): a linear
autoregressive model of the pose (``model``, ``training``, ``file``) and the prior that registers it (``prior``)."""

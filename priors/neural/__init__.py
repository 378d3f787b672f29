"""A neural autoregressive motion prior: a mixture density network over a small MLP encoder of the history
(Bishop 1994; the kind of next-pose model learned motion priors use since, e.g. Ling et al. 2020, Rempe et al.
2021): its settings, model, training, model file and tracking prior."""

"""The Gaussian process dynamical model (Wang 2005): its model, prediction, training, model file and tracking
prior."""

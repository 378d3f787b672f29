"""The conditional restricted Boltzmann machine (Taylor 2009, Ch. 4): its model, training, model file and tracking
prior."""

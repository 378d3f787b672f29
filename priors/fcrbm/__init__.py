"""The factored, style-gated CRBM (Taylor & Hinton 2009): its model, training, model file and tracking prior."""

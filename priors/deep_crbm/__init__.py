"""The two-layer CRBM (Taylor 2009, Sec. 4.3): its model, training, model file and tracking prior."""

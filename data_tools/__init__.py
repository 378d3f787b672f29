"""Mocap readers (ASF/AMC, BVH), retargeting to the body model, sequence formats. Imports only ``tracker``."""

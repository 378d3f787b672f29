"""Geometry core and inference: body model, kinematics, cameras, pose representation, metrics, command line.

Conventions (docs/conventions.md): world z up, millimetres, radians, images
H x W with (x, y) pixel coordinates, batches on the leading axis.
"""
__version__ = "0.1.0"

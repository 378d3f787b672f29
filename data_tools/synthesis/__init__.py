"""Synthetic multi-view sequences: a numpy triangle rasteriser (``raster``), a person rendered as smooth meshes over
a cluttered room (``render``), the settings of a synthetic sequence declared once (``synth_settings``) and real
mocap retargeted and rendered into a calibrated rig (``synth``). Imports the layers below it
(``sequences``, ``motion``, ``io``), never ``data_tools.vision``."""

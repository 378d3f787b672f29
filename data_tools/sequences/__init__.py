"""Multi-view sequences on disk: the project's own layout and PARSEC bodytrack's (``sequence``, ``bodytrack``),
cameras (``calibration``; other tools' calibration files in ``rig_formats``), a sequence's 2-D keypoint file
(``keypoint_file``), pose files (``estimates``) and a run against another method's TRC reconstruction
(``reference``). Imports ``data_tools.motion`` and ``data_tools.io`` below it."""

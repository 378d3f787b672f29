"""Files in and out, the lowest layer of ``data_tools``: checked reading of text, JSON and ``.npz`` (``textfiles``,
``checks``: one refusal naming the file, the value and the range expected), writes that a failure never leaves
half-written (``files``) and content fingerprints of a run's inputs (``fingerprints``). Imports only
``tracker.core``."""

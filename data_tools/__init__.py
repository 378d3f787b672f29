"""Mocap readers (ASF/AMC, BVH), retargeting to the body model, sequence formats. Imports only ``tracker``.

The package is laid out by layer; a layer imports only the layers below it (``pyproject.toml``'s import-linter
contracts)::

    vision | synthesis   video files in, person segmentation, landmarks, 2-D keypoints | rendered sequences
    sequences            multi-view sequences on disk: cameras, images, keypoint files, pose files, references
    motion               motion capture: readers by suffix, retargeting, the converted-clip cache, corpora
    io                   checked reading of text, JSON and npz; atomic writes; content fingerprints

``samples`` is shipped data (two CMU trials), not a layer.
"""

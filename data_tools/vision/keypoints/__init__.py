"""2-D keypoints of a sequence: detector layouts mapped to the body model's keypoints, readers of other tools'
files, detection, the cache in ``seq/keypoints/``, a detector noise model and robust triangulation."""

"""Real footage in: videos imported into sequence folders (``video``), the person's silhouette from a
segmentation model (``person_segmentation``), segment lengths from triangulated image landmarks (``landmarks``)
and 2-D keypoints (``keypoints``: detector layouts, other tools' files, detection, a detector noise model,
robust triangulation). Imports the layers below it (``sequences``, ``motion``, ``io``), never
``data_tools.synthesis``."""

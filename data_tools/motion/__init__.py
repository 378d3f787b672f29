"""Motion capture: clips as joint positions (``mocap``), the readers by suffix (``readers``, ``load``; ASF/AMC in
``asf_amc``, BVH in ``bvh``, TRC marker files in ``trc``) and the naming conventions that find the body's markers
(``joint_names``, ``skeleton_points``), retargeting to the body model (``retarget``), the converted-clip cache
(``cache``) and files (``clip_io``), corpora and their labels (``corpus``), CMU trials downloaded and checked
(``cmu_trials``, ``fetch``), clips that change activity (``transition``) and tracked poses out as BVH
(``bvh_export``). Imports ``data_tools.io`` below it."""

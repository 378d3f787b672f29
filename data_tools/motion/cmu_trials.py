"""What the package knows of the CMU Graphics Lab Motion Capture Database's files that its experiments and
guides use, so that a downloaded copy can be checked by its content (``pose-tracker fetch``;
:mod:`data_tools.motion.fetch`).

The site's exact bytes are not recorded: copies found elsewhere differ in line endings and header lines and are
the same data. A skeleton is recorded by its bones (every CMU skeleton has the same 30) and the sum of its bone
lengths in the file's unit (each subject's own); a trial by its number of frames (120 Hz).
"""
from __future__ import annotations

#: The bones of every CMU ASF skeleton, in the files' order.
CMU_BONES = (
    "lhipjoint", "lfemur", "ltibia", "lfoot", "ltoes", "rhipjoint", "rfemur", "rtibia", "rfoot", "rtoes",
    "lowerback", "upperback", "thorax", "lowerneck", "upperneck", "head", "lclavicle", "lhumerus", "lradius",
    "lwrist", "lhand", "lfingers", "lthumb", "rclavicle", "rhumerus", "rradius", "rwrist", "rhand", "rfingers",
    "rthumb",
)

#: Subject (two digits or more, as the site names its folders) -> sum of the skeleton's bone lengths, in the
#: ASF's own length unit (``:units length 0.45``: 56.44 mm).
SKELETON_LENGTHS = {
    "02": 83.7023, "07": 82.4624, "09": 85.9552, "16": 85.0675, "49": 82.1984, "91": 73.6686,
}

#: Trial (``<subject>_<trial>``) -> frames in its AMC file.
TRIAL_FRAMES = {
    "02_01": 343, "02_02": 298, "02_03": 173, "02_05": 1854,
    "07_01": 316, "07_02": 329, "07_09": 306, "07_10": 301, "07_11": 315,
    "09_01": 148, "09_02": 130, "09_03": 128, "09_04": 137, "09_05": 143, "09_06": 141, "09_07": 138,
    "09_08": 128, "09_10": 132, "09_11": 165,
    "16_15": 471, "16_35": 162, "16_36": 189, "16_45": 135, "16_46": 136, "16_55": 181, "16_56": 169,
    "49_18": 1102, "49_19": 957, "49_20": 898,
}

#: Files some experiments and guides name by their motion rather than by a CMU trial number: they are takes of
#: the subject as other public projects redistribute them, and which of the database's trials each one is could
#: not be established (the subject's index lists candidates by description; the frame counts are not public).
#: They cannot be downloaded; each maps to the candidates that its description fits.
NOT_DOWNLOADABLE = {
    "07_slow_walk": "07_04 or 07_05 ('slow walk')",
    "91_straight_walk": "91_02 or 91_36 ('WalkStraight')",
    "91_slow_walk": "91_10 or 91_27 ('SlowWalk')",
    "91_sad_walk": "91_13 ('SadWalk'), not confirmed",
}

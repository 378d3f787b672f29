"""The mocap-reader contract (:mod:`data_tools.motion.readers`) as a base class of tests.

A subclass sets :attr:`MocapReaderContract.suffix`, :attr:`~MocapReaderContract.reader_name`,
:attr:`~MocapReaderContract.fps` and :attr:`~MocapReaderContract.frames`, and fills
:meth:`MocapReaderContract.make_file` with a file of a person standing or walking upright (most frames); every
``test_*`` method then checks that the file, read as a user reads it (:func:`data_tools.motion.load.load_mocap`,
which finds the reader by the suffix), gives:

- names: one unique name per point, and the body's 15 markers and fit points found from them;
- rate: the file's frame rate (Hz) and every frame;
- units: millimetres (a thigh and a shin of human length, rigid over the frames; a human stature);
- up axis: z (the head above the pelvis, the trunk along +z);
- refusals: a bad file (by default an empty one) refused with one line naming the file.
"""
from __future__ import annotations

from pathlib import Path

import numpy as np

from data_tools.motion.load import load_mocap, reader_for
from data_tools.motion.mocap import MocapClip, marker_positions
from tracker.core.body import MARKER_NAMES
from tracker.core.errors import InputError

_M = {name: i for i, name in enumerate(MARKER_NAMES)}
#: Human ranges (mm) wide enough for any adult and narrow enough to tell mm from cm, inches or metres.
THIGH_MM = (250.0, 650.0)
SHIN_MM = (250.0, 650.0)
STATURE_MM = (1000.0, 2300.0)


class MocapReaderContract:
    """Checks a mocap reader against the contract every mocap reader keeps.

    Subclass it in a test module (as ``TestMyReader(MocapReaderContract)``), set the class attributes and fill
    :meth:`make_file`; override :meth:`read` where the format needs more than the path (a skeleton file).
    """

    #: The suffix the reader is registered for (``".bvh"``).
    suffix: str = ""
    #: The name it is registered with (``"BVH"``).
    reader_name: str = ""
    #: The frame rate (Hz) and the frame count of :meth:`make_file`'s file.
    fps: float = 0.0
    frames: int = 0

    # --- what a subclass provides ---------------------------------------------------------------------

    def make_file(self, folder: Path) -> Path:
        """A file of the format (with any companion files beside it), written into ``folder`` or found."""
        raise NotImplementedError(f"{type(self).__name__} must implement make_file(folder) -> Path")

    def read(self, path: Path) -> MocapClip:
        """``path`` read as a user reads it (default :func:`~data_tools.motion.load.load_mocap` of the path alone)."""
        return load_mocap(path)

    def make_bad_file(self, folder: Path) -> Path:
        """A file the reader must refuse: by default an empty file with the suffix."""
        path = folder / f"empty{self.suffix}"
        path.write_bytes(b"")
        return path

    # --- the contract ---------------------------------------------------------------------------------

    def _clip(self, folder: Path) -> MocapClip:
        clip = self.read(self.make_file(folder))
        assert isinstance(clip, MocapClip), f"the reader gave a {type(clip).__name__}, not a MocapClip"
        return clip

    def test_the_suffix_finds_this_reader(self, tmp_path):
        path = self.make_file(tmp_path)
        assert path.suffix.lower() == self.suffix.lower()
        reader = reader_for(path)
        assert (reader.suffix, reader.name) == (self.suffix.lower(), self.reader_name), reader

    def test_every_point_has_one_unique_name(self, tmp_path):
        clip = self._clip(tmp_path)
        T, J = clip.positions.shape[:2]
        assert clip.positions.shape == (T, J, 3) and np.issubdtype(clip.positions.dtype, np.floating)
        assert np.all(np.isfinite(clip.positions))
        assert len(clip.point_names) == J and len(set(clip.point_names)) == J, clip.point_names
        assert all(isinstance(n, str) and n for n in clip.point_names)
        points = marker_positions(clip)
        assert points.shape[:2] == (T, len(MARKER_NAMES) + 4) and np.all(np.isfinite(points))

    def test_the_rate_and_frames_are_the_files(self, tmp_path):
        clip = self._clip(tmp_path)
        assert clip.fps == self.fps or abs(clip.fps - self.fps) <= 1e-6 * self.fps, (clip.fps, self.fps)
        assert clip.n_frames == self.frames

    def test_lengths_are_millimetres(self, tmp_path):
        m = marker_positions(self._clip(tmp_path))
        for (a, b), (lo, hi) in ((("left_hip", "left_knee"), THIGH_MM), (("right_hip", "right_knee"), THIGH_MM),
                                 (("left_knee", "left_ankle"), SHIN_MM), (("right_knee", "right_ankle"), SHIN_MM)):
            length = np.linalg.norm(m[:, _M[a]] - m[:, _M[b]], axis=-1)
            assert lo < np.median(length) < hi, f"{a} to {b}: {np.median(length):.4g}, not mm"
            assert np.ptp(length) < 0.1 * np.median(length), f"{a} to {b} changes length over the frames"
        ankles = np.minimum(m[:, _M["left_ankle"], 2], m[:, _M["right_ankle"], 2])
        stature = np.percentile(m[:, _M["head"], 2] - ankles, 95)
        assert STATURE_MM[0] < stature < STATURE_MM[1], f"head {stature:.4g} above the ankles: not mm, or not z up"

    def test_z_is_up(self, tmp_path):
        m = marker_positions(self._clip(tmp_path))
        assert np.mean(m[:, _M["head"], 2] > m[:, _M["pelvis"], 2]) > 0.9, "the head is not above the pelvis"
        trunk = np.median(m[:, _M["thorax"]] - m[:, _M["pelvis"]], axis=0)
        assert trunk[2] > 0.8 * np.linalg.norm(trunk), f"the trunk stands along {trunk}, not +z"

    def test_a_bad_file_is_refused_in_one_line_naming_it(self, tmp_path):
        import pytest

        self.make_file(tmp_path)  # companions (a skeleton) in place: the bad file itself is what is refused
        bad = self.make_bad_file(tmp_path)
        with pytest.raises(InputError) as refused:
            self.read(bad)
        message = str(refused.value)
        assert bad.name in message and "\n" not in message, message

"""The mocap-reader contract (:class:`tracker.testing.MocapReaderContract`) run for the built-in readers: an
ASF/AMC walk (the CMU walk shipped with the package, its skeleton found beside it), a CMU BVH file (y up,
centimetres, 120 Hz; shared data) and a BVH file written here z up in inches at 30 Hz; and the registry that
finds a reader by its file's suffix."""
from __future__ import annotations

import shutil

import pytest

from data_tools.motion.asf_amc import read_asf
from data_tools.samples import sample_walks
from tracker.core.errors import InputError
from tracker.testing import MocapReaderContract


class TestAsfAmc(MocapReaderContract):
    suffix, reader_name, fps, frames = ".amc", "ASF/AMC", 120.0, 316

    def make_file(self, folder):
        asf, amcs = sample_walks()
        shutil.copy(asf, folder / asf.name)
        return shutil.copy(amcs[0], folder / amcs[0].name)


class TestCmuBvh(MocapReaderContract):
    suffix, reader_name, fps, frames = ".bvh", "BVH", 120.0, 363

    @pytest.fixture(autouse=True)
    def shared(self, mocap_dir):
        self.mocap_dir = mocap_dir

    def make_file(self, folder):
        return self.mocap_dir / "bvh" / "10_03.bvh"


class TestZUpInchBvh(MocapReaderContract):
    """1 s of the shipped walk written as BVH with the ASF's bone names, z up, in inches, every 4th frame."""

    suffix, reader_name, fps, frames = ".bvh", "BVH", 30.0, 31

    def make_file(self, folder):
        from tests.bvh_writer import write_bvh

        asf, amcs = sample_walks()
        return write_bvh(folder / "walk.bvh", asf, amcs[0], {b: b for b in read_asf(asf).bones}, root="root",
                         z_up=True, mm_per_unit=25.4, every=4, frames=121)


def test_a_reader_registers_once_per_suffix_and_unknown_suffixes_list_the_registered(tmp_path):
    from data_tools.motion.load import load_mocap, registered_readers
    from data_tools.motion.readers import READERS, register_mocap_reader
    from tracker.engine.registry import Registry

    assert [r.suffix for r in registered_readers()][:2] == [".amc", ".bvh"]
    assert isinstance(READERS, Registry)  # the engine's one registry mechanism, keyed by suffix
    with pytest.raises(InputError, match=r"^mocap files \.bvh are already read by data_tools\.motion\.load\."
                                         r"read_bvh_file \(BVH\); .* cannot take the suffix$"):
        register_mocap_reader(".BVH", "another BVH")(lambda path, options: None)
    for bad in ("bvh", ".", ".tar.gz"):
        with pytest.raises(ValueError, match="one dot and a name"):
            register_mocap_reader(bad, "bad")
    unknown = tmp_path / "clip.c3d"
    unknown.write_text("x")
    with pytest.raises(InputError) as refused:
        load_mocap(unknown)
    message = str(refused.value)
    assert message.startswith(f"{unknown}: unknown mocap format '.c3d': the registered readers take ")
    assert all(r.described() in message for r in READERS.values()) and "\n" not in message
    assert ".amc (ASF/AMC, with its .asf skeleton)" in message


def test_a_skeleton_is_refused_for_a_format_that_carries_its_own(tmp_path):
    from data_tools.motion.load import load_mocap

    bvh = tmp_path / "walk.bvh"
    bvh.write_text("HIERARCHY\n")
    with pytest.raises(InputError, match="a BVH file carries its own skeleton; --skeleton applies to ASF/AMC "
                                         "files only"):
        load_mocap(bvh, skeleton=sample_walks()[0])

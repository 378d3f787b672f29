"""Output files and folders get the modes the umask gives new ones, though they are written through private
temporary files and folders (which are created 0o600 and 0o700) so that a failure leaves nothing half-written."""
from __future__ import annotations

import os

import pytest

from data_tools.io.files import current_umask, write_text_atomic


@pytest.mark.parametrize("umask", [0o022, 0o077, 0o002])
def test_an_atomically_written_file_follows_the_umask(tmp_path, umask):
    old = os.umask(umask)
    try:
        assert current_umask() == umask
        write_text_atomic(tmp_path / "result.json", "{}")
    finally:
        os.umask(old)
    assert (tmp_path / "result.json").stat().st_mode & 0o777 == 0o666 & ~umask


def test_a_rendered_sequence_folder_follows_the_umask(synthetic_walk):
    assert synthetic_walk.root.stat().st_mode & 0o777 == 0o777 & ~current_umask()

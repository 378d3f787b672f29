import numpy as np
import pytest

from data_tools.motion.asf_amc import asf_amc_clip, read_asf
from data_tools.motion.bvh import bvh_clip
from data_tools.motion.load import load_mocap
from data_tools.motion.mocap import frame_times, marker_positions
from tests.conftest import SHARED_CLIPS
from tracker.core.errors import InputError


@pytest.mark.parametrize("rel", sorted(SHARED_CLIPS))
def test_every_shared_clip_loads_plausibly(mocap_dir, rel):
    clip = load_mocap(mocap_dir / rel)
    assert clip.n_frames == SHARED_CLIPS[rel]
    assert clip.fps == pytest.approx(120.0, rel=1e-4)
    m = marker_positions(clip)
    assert np.all(np.isfinite(m))
    # Stature: head marker above the floor (the lowest foot point of the clip) when upright
    # (95th percentile over frames; the kicks and 131_01 bend over much of the time).
    floor = m[:, [11, 14, 17, 18], 2].min()
    head_height = np.percentile(m[:, 2, 2], 95) - floor
    assert 1400 < head_height < 2000
    assert -60 < m[..., 2].min() < 120  # feet reach the floor
    assert np.all(m[:, 2, 2] > m[:, 0, 2])  # head above pelvis


@pytest.mark.parametrize("rel", ["07/07_01.amc", "07/07_02.amc", "07/07_09.amc", "07/07_10.amc", "07/07_11.amc"])
def test_walking_speed(mocap_dir, rel):
    clip = load_mocap(mocap_dir / rel)
    pelvis = marker_positions(clip)[:, 0, :2]
    speed = np.linalg.norm(pelvis[-1] - pelvis[0]) / 1000 / ((clip.n_frames - 1) / clip.fps)
    assert 0.8 < speed < 2.0


def test_bvh_units_inferred(mocap_dir):
    assert bvh_clip(mocap_dir / "bvh" / "10_01.bvh").unit.startswith("cm")
    assert "1/0.45 inch" in bvh_clip(mocap_dir / "bvh" / "131_01.bvh").unit
    explicit = bvh_clip(mocap_dir / "bvh" / "10_01.bvh", mm_per_unit=10.0)
    assert explicit.unit == "10 mm per unit (given)" and not explicit.notes


def test_frame_times_keep_every_kth_frame_and_interpolate_between():
    assert np.array_equal(frame_times(316, 120, 60), np.arange(158) * 2.0)
    odd = frame_times(316, 120, 50)
    assert len(odd) == int((316 - 1) / 120 * 50) + 1 and odd[5] == 12.0 and odd[1] == pytest.approx(2.4)
    assert np.array_equal(frame_times(31, 30, 60), np.arange(61) * 0.5)  # upsampling: halfway between frames
    with pytest.raises(InputError, match="at most 10 times"):
        frame_times(31, 30, 301)
    with pytest.raises(InputError, match=r"within \[0.1, 100000\] Hz"):
        frame_times(316, 120, 0)


# --- bad input -------------------------------------------------------------

@pytest.fixture
def cmu07(mocap_dir, tmp_path):
    asf = tmp_path / "07.asf"
    asf.write_text((mocap_dir / "07" / "07.asf").read_text())
    amc_lines = (mocap_dir / "07" / "07_01.amc").read_text().splitlines()[:200]
    return asf, amc_lines


def write(tmp_path, name, lines):
    p = tmp_path / name
    p.write_text("\n".join(lines) + "\n")
    return p


def test_truncated_amc(cmu07, tmp_path):
    asf, lines = cmu07
    amc = write(tmp_path, "07_01.amc", lines[:-3])  # the last frame loses its last bones
    with pytest.raises(InputError) as err:
        asf_amc_clip(asf, amc)
    assert "07_01.amc" in str(err.value) and "truncated" in str(err.value)


def test_amc_bone_missing_from_asf(cmu07, tmp_path):
    asf, lines = cmu07
    lines = list(lines)
    k = next(i for i, s in enumerate(lines) if s.startswith("rtibia"))
    lines[k] = lines[k].replace("rtibia", "rshin")
    amc = write(tmp_path, "07_01.amc", lines)
    with pytest.raises(InputError) as err:
        asf_amc_clip(asf, amc)
    assert f"07_01.amc:{k + 1}:" in str(err.value) and "rshin" in str(err.value)


@pytest.mark.parametrize("bad_line, message", [("lfemur nan 1 2", "NaN"), ("lfemur 1 two 3", "expected numbers")])
def test_amc_bad_values(cmu07, tmp_path, bad_line, message):
    asf, lines = cmu07
    lines = list(lines)
    k = next(i for i, s in enumerate(lines) if s.startswith("lfemur"))
    lines[k] = bad_line
    with pytest.raises(InputError, match=rf"07_01.amc:{k + 1}:.*{message}"):
        asf_amc_clip(asf, write(tmp_path, "07_01.amc", lines))


def test_malformed_asf(mocap_dir, tmp_path):
    lines = (mocap_dir / "07" / "07.asf").read_text().splitlines()
    k = next(i for i, s in enumerate(lines) if s.strip().startswith("length") and i > 20)
    bad = list(lines)
    bad[k] = "     length abc"
    with pytest.raises(InputError, match=rf"07.asf:{k + 1}:.*bone length"):
        read_asf(write(tmp_path, "07.asf", bad))
    cut = lines[: len(lines) // 3]
    with pytest.raises(InputError, match="07.asf"):
        read_asf(write(tmp_path, "07.asf", cut))


def test_bvh_bad_inputs(mocap_dir, tmp_path):
    lines = (mocap_dir / "bvh" / "10_03.bvh").read_text().splitlines()
    motion = next(i for i, s in enumerate(lines) if s.startswith("MOTION"))
    truncated = write(tmp_path, "t.bvh", lines[:-5])
    with pytest.raises(InputError, match=r"t.bvh: header says 363 frames but the file has 358"):
        bvh_clip(truncated)
    zero_rate = list(lines)
    zero_rate[motion + 2] = "Frame Time: 0"
    with pytest.raises(InputError, match=rf"z.bvh:{motion + 3}:.*frame time must be positive"):
        bvh_clip(write(tmp_path, "z.bvh", zero_rate))
    nan = list(lines)
    vals = nan[motion + 10].split()
    vals[4] = "inf"
    nan[motion + 10] = " ".join(vals)
    with pytest.raises(InputError, match=rf"n.bvh:{motion + 11}:.*NaN or infinite"):
        bvh_clip(write(tmp_path, "n.bvh", nan))
    short = list(lines)
    short[motion + 10] = " ".join(short[motion + 10].split()[:-1])
    with pytest.raises(InputError, match=rf"s.bvh:{motion + 11}:.*channels"):
        bvh_clip(write(tmp_path, "s.bvh", short))


def test_unknown_format(tmp_path):
    p = tmp_path / "clip.c3d"
    p.write_text("x")
    with pytest.raises(InputError, match="unknown mocap format"):
        load_mocap(p)

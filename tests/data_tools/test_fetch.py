"""`pose-tracker fetch` against a local HTTP server standing in for the CMU site (no test touches the network):
files land where experiments look for them, each is checked by parsing before it is put in place, a second run
skips what is there, and every failure (a file the server lacks, a corrupted or truncated file, the server
unreachable) is one line naming the URL with exit status 2."""
from __future__ import annotations

import functools
import http.server
import os
import re
import shlex
import shutil
import socket
import subprocess
import sys
import threading
from pathlib import Path

import pytest

from data_tools.motion.cmu_trials import CMU_BONES, SKELETON_LENGTHS, TRIAL_FRAMES
from data_tools.motion.fetch import fetch_cmu, parse_trial
from tracker.app.experiment import DATA_ROOT_ENV
from tracker.app.fetching import experiment_needs, fetch
from tracker.core.errors import InputError

REPO = Path(__file__).resolve().parents[2]
SAMPLES = REPO / "data_tools" / "samples" / "cmu07"
README = REPO / "README.md"


#: Proxy settings would send the requests to the local server elsewhere.
PROXY_VARIABLES = ("http_proxy", "HTTP_PROXY", "https_proxy", "HTTPS_PROXY", "all_proxy", "ALL_PROXY")


@pytest.fixture(autouse=True)
def no_proxy(monkeypatch):
    for name in PROXY_VARIABLES:
        monkeypatch.delenv(name, raising=False)


class _Handler(http.server.SimpleHTTPRequestHandler):
    requested: list[str]

    def do_GET(self):  # noqa: N802 (the base class's name)
        self.requested.append(self.path)
        super().do_GET()

    def log_message(self, *args) -> None:  # quiet
        pass


@pytest.fixture
def server(tmp_path):
    """A local HTTP server on a free port over ``site/`` (laid out as the CMU site's ``subjects`` folder): the
    shipped sample (07.asf, 07_01, 07_02), a corrupted motion (07_09), one cut at a frame boundary (07_10) and
    one cut inside a frame (07_11); 07_12 is missing (404); 16.asf is subject 7's skeleton under another name."""
    site = tmp_path / "site"
    (site / "07").mkdir(parents=True)
    (site / "16").mkdir()
    for name in ("07.asf", "07_01.amc", "07_02.amc"):
        shutil.copy(SAMPLES / name, site / "07" / name)
    lines = (SAMPLES / "07_01.amc").read_text().splitlines(keepends=True)
    corrupted = [line.replace("lfemur", "lfemmur") for line in lines]
    (site / "07" / "07_09.amc").write_text("".join(corrupted))
    frame_200 = lines.index("200\n")
    (site / "07" / "07_10.amc").write_text("".join(lines[:frame_200]))  # frames 1-199, each complete
    (site / "07" / "07_11.amc").write_text("".join(lines[:frame_200 + 5]))  # frame 200 cut after 4 bones
    shutil.copy(SAMPLES / "07.asf", site / "16" / "16.asf")
    requested: list[str] = []
    handler = type("Handler", (_Handler,), {"requested": requested})
    httpd = http.server.ThreadingHTTPServer(("127.0.0.1", 0), functools.partial(handler, directory=str(site)))
    thread = threading.Thread(target=httpd.serve_forever, daemon=True)
    thread.start()
    try:
        yield f"http://127.0.0.1:{httpd.server_address[1]}", requested
    finally:
        httpd.shutdown()
        httpd.server_close()


def closed_port_url() -> str:
    """A URL on a port nothing listens on (bound, then closed)."""
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        port = s.getsockname()[1]
    return f"http://127.0.0.1:{port}"


def cli(*args: str, env_extra: dict | None = None, cwd: Path = REPO) -> subprocess.CompletedProcess:
    env = {k: v for k, v in os.environ.items() if k != DATA_ROOT_ENV and k not in PROXY_VARIABLES}
    env["PYTHONPATH"] = os.pathsep.join([str(REPO), env.get("PYTHONPATH", "")])
    env.update(env_extra or {})
    return subprocess.run([sys.executable, "-m", "tracker", *args], capture_output=True, text=True, env=env,
                          cwd=cwd, timeout=300)


def test_trials_are_placed_where_experiments_look_for_them_and_checked(server, tmp_path):
    url, requested = server
    placed = fetch_cmu(["07_01", "7_2"], tmp_path / "data", mirror=url)
    folder = tmp_path / "data" / "mocap" / "cmu" / "07"
    assert placed == [folder / "07.asf", folder / "07_01.amc", folder / "07_02.amc"]
    for name in ("07.asf", "07_01.amc", "07_02.amc"):
        assert (folder / name).read_bytes() == (SAMPLES / name).read_bytes()
    assert sorted(requested) == ["/07/07.asf", "/07/07_01.amc", "/07/07_02.amc"]
    assert not list(folder.glob("*.part"))


def test_a_second_run_skips_valid_files_and_replaces_partial_and_bad_ones(server, tmp_path):
    url, requested = server
    root = tmp_path / "data"
    fetch_cmu(["07_01", "07_02"], root, mirror=url)
    requested.clear()
    folder = root / "mocap" / "cmu" / "07"
    (folder / "07_02.amc").rename(folder / "07_02.amc.part")  # as an interrupted download leaves it
    (folder / "07_02.amc.part").write_text("1\nroot 0 0")
    (folder / "07_01.amc").write_text((SAMPLES / "07_01.amc").read_text()[:5000])  # a damaged copy in place
    before = (folder / "07.asf").stat().st_mtime_ns
    fetch_cmu(["07_01", "07_02"], root, mirror=url)
    assert sorted(requested) == ["/07/07_01.amc", "/07/07_02.amc"]  # the valid skeleton is kept
    assert (folder / "07.asf").stat().st_mtime_ns == before
    assert (folder / "07_01.amc").read_bytes() == (SAMPLES / "07_01.amc").read_bytes()
    assert (folder / "07_02.amc").read_bytes() == (SAMPLES / "07_02.amc").read_bytes()
    assert not (folder / "07_02.amc.part").exists()
    requested.clear()
    fetch_cmu(["07_01", "07_02"], root, mirror=url)
    assert requested == []


@pytest.mark.parametrize("trial, problem", [
    ("07_09", "not a readable AMC motion of 07.asf"),          # corrupted: a bone the skeleton lacks
    ("07_10", "199 frames where trial 07_10 has 301"),         # cut at a frame boundary: it parses, too short
    ("07_11", "not a readable AMC motion of 07.asf"),          # cut inside a frame
    ("07_12", "HTTP 404"),                                     # not on the server
    ("16_15", "not subject 16's skeleton"),                    # another subject's skeleton under its name
])
def test_a_wrong_file_is_refused_in_one_line_naming_the_url_and_nothing_is_left(server, tmp_path, trial, problem):
    url, _ = server
    root = tmp_path / "data"
    with pytest.raises(InputError) as err:
        fetch_cmu([trial], root, mirror=url)
    message = str(err.value)
    subject = trial[:2]
    file = f"{subject}.asf" if trial == "16_15" else f"{trial}.amc"
    assert message.startswith(f"{url}/{subject}/{file}: ") and problem in message and "\n" not in message
    folder = root / "mocap" / "cmu" / subject
    assert not (folder / file).exists() and not list(folder.glob("*.part"))


@pytest.mark.slow
def test_the_command_line_fetches_and_refuses_in_one_line(server, tmp_path):
    url, _ = server
    done = cli("fetch", "cmu", "07_01", "--data-root", str(tmp_path / "data"), "--mirror", url)
    assert done.returncode == 0, done.stderr
    assert (tmp_path / "data" / "mocap" / "cmu" / "07" / "07_01.amc").is_file()
    done = cli("fetch", "cmu", "07_12", "--mirror", url, env_extra={DATA_ROOT_ENV: str(tmp_path / "data")})
    assert done.returncode == 2
    lines = done.stderr.strip().splitlines()
    assert lines[-1] == f"pose-tracker: error: {url}/07/07_12.amc: the server answered HTTP 404 (File not found)"
    assert not any("error" in line for line in lines[:-1]), done.stderr


def test_offline_is_one_line_naming_the_url_with_status_2(tmp_path):
    url = closed_port_url()
    done = cli("fetch", "cmu", "07_01", "--data-root", str(tmp_path / "data"), "--mirror", url, "--timeout", "5")
    assert done.returncode == 2
    lines = done.stderr.strip().splitlines()
    assert len(lines) == 1 and "Traceback" not in done.stderr, done.stderr
    assert lines[0].startswith(f"pose-tracker: error: {url}/07/07.asf: cannot reach the server")
    assert not (tmp_path / "data").exists()  # nor the folders made for the files


def test_a_failed_file_leaves_no_folder_made_for_it(server, tmp_path):
    url, _ = server
    root = tmp_path / "data"
    fetch_cmu(["07_01"], root, mirror=url)
    with pytest.raises(InputError, match="not subject 16's skeleton"):
        fetch_cmu(["16_15"], root, mirror=url)
    assert sorted(p.name for p in (root / "mocap" / "cmu").iterdir()) == ["07"]
    with pytest.raises(InputError, match="HTTP 404"):
        fetch_cmu(["07_12"], root, mirror=url)  # the folder holds the skeleton and 07_01: it stays
    assert sorted(p.name for p in (root / "mocap" / "cmu" / "07").iterdir()) == ["07.asf", "07_01.amc"]
    existing = tmp_path / "existing"
    existing.mkdir()
    with pytest.raises(InputError, match="not subject 16's skeleton"):
        fetch_cmu(["16_15"], existing, mirror=url)
    assert existing.is_dir() and not list(existing.iterdir())  # the root was there before: it stays, empty


@pytest.mark.slow
def test_a_data_root_under_a_file_is_one_line_naming_the_file(server, tmp_path):
    url, _ = server
    afile = tmp_path / "afile"
    afile.write_text("not a folder")
    done = cli("fetch", "cmu", "07_01", "--data-root", str(afile / "sub"), "--mirror", url)
    assert done.returncode == 2 and "Traceback" not in done.stderr, done.stderr
    assert done.stderr.strip().splitlines() == [
        f"pose-tracker: error: {afile}: not a folder, so {afile / 'sub' / 'mocap' / 'cmu' / '07'} cannot be created"]
    assert afile.read_text() == "not a folder"


@pytest.mark.slow
@pytest.mark.skipif(not Path("/proc/self").is_dir(), reason="needs /proc, where no folder can be made")
def test_a_data_root_that_cannot_be_made_is_one_line_naming_it(server, tmp_path):
    url, _ = server
    done = cli("fetch", "cmu", "07_01", "--data-root", "/proc/no_such_root", "--mirror", url)
    assert done.returncode == 2 and "Traceback" not in done.stderr, done.stderr
    lines = done.stderr.strip().splitlines()
    assert len(lines) == 1 and lines[0].startswith("pose-tracker: error: /proc/no_such_root: cannot create the "
                                                   "folder ("), done.stderr


@pytest.mark.slow
@pytest.mark.parametrize("in_the_way, problem", [
    ("07.asf.part", "cannot write the download"),  # the download's temporary file cannot be written
    ("07.asf", "cannot put the download in place"),  # the checked download cannot be renamed
])
def test_a_file_that_cannot_be_written_is_one_line_naming_it(server, tmp_path, in_the_way, problem):
    url, _ = server
    folder = tmp_path / "data" / "mocap" / "cmu" / "07"
    (folder / in_the_way).mkdir(parents=True)  # a folder where the file goes
    done = cli("fetch", "cmu", "07_01", "--data-root", str(tmp_path / "data"), "--mirror", url)
    assert done.returncode == 2 and "Traceback" not in done.stderr, done.stderr
    lines = done.stderr.strip().splitlines()
    assert len(lines) == 1 and lines[0].startswith(f"pose-tracker: error: {folder / in_the_way}: {problem} ("), \
        done.stderr
    assert sorted(p.name for p in folder.iterdir()) == [in_the_way]  # nothing else left


@pytest.mark.slow
def test_the_database_may_be_left_out(server, tmp_path):
    url, _ = server
    done = cli("fetch", "07_01", "7_2", "--data-root", str(tmp_path / "data"), "--mirror", url)
    assert done.returncode == 0, done.stderr
    folder = tmp_path / "data" / "mocap" / "cmu" / "07"
    assert sorted(p.name for p in folder.iterdir()) == ["07.asf", "07_01.amc", "07_02.amc"]


@pytest.mark.parametrize("args, problem", [
    (["cmu", "7-1", "--data-root", "d"], "'7-1' is not a CMU trial"),
    (["7-1", "--data-root", "d"], "'7-1' is not a CMU trial"),
    (["mocap", "07_01", "--data-root", "d"], "'mocap' is not a CMU trial"),
    (["cmu", "91_straight_walk", "--data-root", "d"], "91_straight_walk is not one of the CMU database's trial names"),
    (["cmu", "07_01"], "say where the data goes"),
    (["--data-root", "d"], "nothing to fetch"),
    (["cmu", "07_01", "--data-root", "d", "--mirror", "ftp://x"], "expected an http://"),
])
def test_bad_requests_are_one_line(tmp_path, args, problem):
    done = cli("fetch", *args, cwd=tmp_path)
    assert done.returncode == 2
    lines = done.stderr.strip().splitlines()
    assert len(lines) == 1 and problem in lines[0], done.stderr


def test_trial_names():
    assert parse_trial("07_01").name == "07_01" and parse_trial("131_4").name == "131_04"
    assert parse_trial("16_15.amc").files() == ("16/16.asf", "16/16_15.amc")
    for bad in ("0_1", "07", "07_001", "a_01"):
        with pytest.raises(InputError):
            parse_trial(bad)


def test_the_record_matches_the_shipped_sample():
    from data_tools.motion.asf_amc import read_amc, read_asf

    skeleton = read_asf(SAMPLES / "07.asf")
    assert skeleton.order() == list(CMU_BONES)
    assert sum(b.length for b in skeleton.bones.values()) == pytest.approx(SKELETON_LENGTHS["07"], abs=1e-4)
    for trial in ("07_01", "07_02"):
        assert len(read_amc(SAMPLES / f"{trial}.amc", read_asf(SAMPLES / "07.asf"))["root"]) == TRIAL_FRAMES[trial]


@pytest.mark.slow
def test_the_record_matches_the_shared_copies(mocap_dir):
    from data_tools.motion.asf_amc import read_amc, read_asf

    for subject, length in SKELETON_LENGTHS.items():
        skeleton = read_asf(mocap_dir / subject / f"{subject}.asf")
        assert sum(b.length for b in skeleton.bones.values()) == pytest.approx(length, abs=1e-4), subject
    for trial, frames in TRIAL_FRAMES.items():
        subject = trial.split("_")[0]
        motion = read_amc(mocap_dir / subject / f"{trial}.amc", read_asf(mocap_dir / subject / f"{subject}.asf"))
        assert len(motion["root"]) == frames, trial


def test_every_cmu_trial_the_shipped_experiments_name_is_recorded_or_known_as_shared_only():
    for path in sorted((REPO / "benchmarks" / "experiments").rglob("*.toml")):
        _, trials, _ = experiment_needs(path, data_root="unused")
        assert set(trials) <= set(TRIAL_FRAMES), (path, set(trials) - set(TRIAL_FRAMES))


def test_an_experiment_naming_shared_only_files_fetches_the_rest_then_says_so(server, tmp_path):
    url, _ = server
    exp = tmp_path / "exp.toml"
    exp.write_text('data_root = "data"\n[[sequence]]\nmocap = "mocap/cmu/07/07_02.amc"\n'
                   '[[prior]]\nname = "zero-velocity"\ntrain_mocap = ["mocap/cmu/91/91_straight_walk.amc"]\n')
    with pytest.raises(InputError, match="91_straight_walk.amc not found under .*cannot be downloaded"):
        fetch(experiment=exp, mirror=url)
    assert (tmp_path / "data" / "mocap" / "cmu" / "07" / "07_02.amc").is_file()


@pytest.mark.slow
def test_without_its_data_compare_names_the_command_that_fetches_it(tmp_path):
    exp = tmp_path / "clone" / "benchmarks" / "experiments" / "walk_unseen_subject.toml"
    exp.parent.mkdir(parents=True)
    shutil.copy(REPO / "benchmarks" / "experiments" / "walk_unseen_subject.toml", exp)
    done = cli("compare", str(exp), "--out", str(tmp_path / "out"))
    assert done.returncode == 2
    lines = done.stderr.strip().splitlines()
    assert len(lines) == 1 and "data root not found" in lines[0], done.stderr
    assert f"`pose-tracker fetch --for {exp}`" in lines[0]
    (tmp_path / "shared").mkdir()  # the root is there, the files not
    done = cli("compare", str(exp), "--out", str(tmp_path / "out"))
    lines = done.stderr.strip().splitlines()
    assert done.returncode == 2 and len(lines) == 1 and "16_15.amc" in lines[0], done.stderr
    assert f"`pose-tracker fetch --for {exp}`" in lines[0]


def named_fetch(stderr: str) -> list[str]:
    """The words of the `pose-tracker fetch ...` command a one-line refusal names."""
    (command,) = re.findall(r"`(pose-tracker fetch [^`]*)`", stderr)
    return shlex.split(command)


@pytest.mark.slow
@pytest.mark.parametrize("how", ["--data-root", DATA_ROOT_ENV])
def test_the_command_compare_names_fetches_where_compare_looks(tmp_path, monkeypatch, how):
    """With the data root given (``--data-root``, or the environment variable), the named command puts the files
    there, also run in a shell without the variable: the root missing, or there without the files."""
    from tracker.app.parser import build_parser

    exp = REPO / "benchmarks" / "experiments" / "walk_unseen_subject.toml"
    for root in (tmp_path / "missing", tmp_path / "empty"):
        if root.name == "empty":
            root.mkdir()
        given = (["--data-root", str(root)], {}) if how == "--data-root" else ([], {DATA_ROOT_ENV: str(root)})
        done = cli("compare", str(exp), "--out", str(tmp_path / "out"), *given[0], env_extra=given[1])
        lines = done.stderr.strip().splitlines()
        assert done.returncode == 2 and len(lines) == 1, done.stderr
        assert ("data root not found" if root.name == "missing" else "16_15.amc") in lines[0]
        words = named_fetch(lines[0])
        args = build_parser(words[1:]).parse_args(words[1:])
        monkeypatch.delenv(DATA_ROOT_ENV, raising=False)
        assert experiment_needs(args.experiment, args.data_root)[0] == root, lines[0]


#: What the end-to-end test shrinks in its copy of the README's experiment: each must appear in the file.
TINY_EXPERIMENT = {"seeds = 3": "seeds = 1", "particles = 500": "particles = 30", "frames = 100": "frames = 6",
                   "views = [0, 1, 2, 3]": "views = [0]",
                   "options = { order = 1 }": "options = { order = 1, epochs = 2 }"}


@pytest.mark.slow
def test_the_readme_compare_example_runs_after_the_documented_fetch(tmp_path, mocap_dir):
    """The README's comparison block, as written, on a fresh data root: the fetch from a local copy of the CMU
    site (made from the shared files), then compare on a copy of the experiment cut to a few frames."""
    site = tmp_path / "site"
    block = next(b for b in README.read_text().split("```") if "pose-tracker compare" in b)
    lines = [line.split("  #")[0].strip() for line in block.splitlines() if line.startswith("pose-tracker")]
    assert [shlex.split(line)[1] for line in lines] == ["fetch", "compare"], lines
    experiment = REPO / shlex.split(lines[1])[2]
    _, trials, shared_only = experiment_needs(experiment, data_root="unused")
    assert trials and not shared_only
    for trial in trials:
        subject = trial.split("_")[0]
        (site / subject).mkdir(parents=True, exist_ok=True)
        for name in (f"{subject}.asf", f"{trial}.amc"):
            shutil.copy(mocap_dir / subject / name, site / subject / name)
    requested: list[str] = []
    handler = type("Handler", (_Handler,), {"requested": requested})
    httpd = http.server.ThreadingHTTPServer(("127.0.0.1", 0), functools.partial(handler, directory=str(site)))
    threading.Thread(target=httpd.serve_forever, daemon=True).start()
    try:
        url = f"http://127.0.0.1:{httpd.server_address[1]}"
        root = tmp_path / "data"
        env = {DATA_ROOT_ENV: str(root), "OMP_NUM_THREADS": "1"}
        fetch_args = shlex.split(lines[0])[1:] + ["--mirror", url]
        done = cli(*fetch_args, env_extra=env)
        assert done.returncode == 0, done.stderr
    finally:
        httpd.shutdown()
        httpd.server_close()
    assert len(requested) == len(trials) + len({t.split("_")[0] for t in trials})
    text = experiment.read_text()
    for big, small in TINY_EXPERIMENT.items():
        assert big in text, big
        text = text.replace(big, small)
    tiny = tmp_path / experiment.name
    tiny.write_text(text)
    compare_args = shlex.split(lines[1])[1:]
    compare_args[1] = str(tiny)
    compare_args[compare_args.index("--out") + 1] = str(tmp_path / "results")
    done = cli("--threads", "1", *compare_args, "--no-videos", env_extra=env, cwd=tmp_path)
    assert done.returncode == 0, done.stderr[-2000:]
    table = (tmp_path / "results" / "table.md").read_text()
    for prior in ("zero-velocity", "constant-velocity", "CRBM-1"):
        assert prior in table

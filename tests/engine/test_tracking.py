"""Likelihood and tracking on synthetic and real frames; the track command."""
import json
import subprocess
import sys

import numpy as np
import pytest

from likelihoods.edge_silhouette import EdgeSilhouetteLikelihood, EdgeSilhouetteConfig
from priors.random_walk import ConstantVelocityPrior, ZeroVelocityPrior
from tracker.app.cli import main
from tracker import track
from tracker.core.kinematics import markers


def test_log_likelihood_peaks_at_the_true_pose(walk_32_frames):
    seq = walk_32_frames
    k = 20
    lik = EdgeSilhouetteLikelihood(seq.model, seq.rig).prepare(seq.frame(k, range(4)))
    truth = seq.groundtruth.poses[k]
    best = lik(truth[None])[0]
    m0 = markers(seq.model, truth)
    checked = 0
    for d in range(seq.model.n_dofs):
        for delta in ((-80.0, 80.0) if d < 3 else (-0.3, 0.3)):
            q = truth.copy()
            q[d] += delta
            if not seq.model.within_limits(q):
                continue
            moved = np.linalg.norm(markers(seq.model, q) - m0, axis=-1).mean()
            if moved < 15.0:  # twists of round cones barely change the picture
                continue
            checked += 1
            assert lik(q[None])[0] < best, (seq.model.dof_names[d], delta)
    assert checked >= 30


def test_likelihood_terms_and_limits(walk_32_frames):
    seq = walk_32_frames
    lik = EdgeSilhouetteLikelihood(seq.model, seq.rig, EdgeSilhouetteConfig(bidirectional=True)).prepare(
        seq.frame(5, range(4)))
    truth = seq.groundtruth.poses[5]
    shifted = truth.copy()
    shifted[0] += 300.0
    outside = truth.copy()
    outside[seq.model.dof_index("left_knee_flexion")] = -1.0
    t = lik.terms(np.stack([truth, shifted, outside]))
    assert t.edge.shape == (3, 4) and np.all((t.edge >= 0) & (t.edge <= 1))
    assert np.all(t.silhouette[0] < 0.1) and np.all(t.coverage[0] < 0.2)
    assert np.all(t.coverage[1] > t.coverage[0]) and t.log_likelihood[1] < t.log_likelihood[0]
    assert t.log_likelihood[2] == -np.inf


@pytest.mark.slow
def test_thirty_frame_walk_tracked_within_bound(walk_32_frames, random_walk_std):
    # Measured before setting the bound (500 particles, 4 views, seeds 0-5): 44.5-54.6 mm mean, 65-81 mm worst
    # frame. A filter that ignores the images drifts to about 417 mm on the same frames.
    run = track(walk_32_frames, ZeroVelocityPrior(random_walk_std), particles=500, seed=0)
    assert run.first_tracked == 2 and len(run.errors) == 30
    assert run.mean_error < 80.0 and run.errors.max() < 130.0


def test_same_seed_same_tracking(walk_32_frames, random_walk_std):
    def run(seed):
        return track(walk_32_frames, ConstantVelocityPrior(random_walk_std), particles=100, seed=seed,
                     frames=6).poses
    a, b, c = run(3), run(3), run(4)
    assert np.array_equal(a, b) and not np.array_equal(a, c)


def test_track_command_writes_design_outputs(walk_32_frames, tmp_path):
    out = tmp_path / "run"
    assert main(["track", str(walk_32_frames.root), "--prior", "zero-velocity", "--particles", "200",
                 "--views", "0,2", "--frames", "6", "--seed", "1", "--out", str(out),
                 "--video", str(tmp_path / "o.mp4")]) == 0
    res = json.loads((out / "result.json").read_text())
    for key in ("prior", "particles", "views", "seed", "frames", "frames_known", "frames_tracked", "metrics",
                "seconds_per_frame", "invocation", "started", "finished"):
        assert key in res, key
    assert res["views"] == [0, 2] and (res["frames"], res["frames_known"], res["frames_tracked"]) == (6, 2, 4)
    error = res["metrics"]["mpjpe_abs"]
    assert len(error["per_frame"]) == 4 and error["mean"] == pytest.approx(np.mean(error["per_frame"]), abs=1e-3)
    import tracker
    assert res["version"] == tracker.__version__
    with np.load(out / "estimates.npz") as z:
        assert z["poses"].shape == (6, 40) and z["markers"].shape == (6, 15, 3)
    assert (tmp_path / "o.mp4").stat().st_size > 1000
    from data_tools.io.files import current_umask
    assert (out / "result.json").stat().st_mode & 0o777 == 0o666 & ~current_umask()  # as any new file


def test_track_bodytrack_without_ground_truth(bodytrack_dir, tmp_path):
    out = tmp_path / "bt"
    assert main(["track", str(bodytrack_dir), "--prior", "zero-velocity", "--particles", "200",
                 "--annealing-layers", "3", "--out", str(out)]) == 0
    res = json.loads((out / "result.json").read_text())
    assert res["frames"] == res["frames_tracked"] == 1 and res["metrics"] is None
    assert res["model"] == "bodytrack-10-cone"
    with np.load(out / "estimates.npz") as z:
        assert z["poses"].shape == (1, 31) and np.all(np.isfinite(z["poses"]))


def torch_has_cuda() -> bool:
    import torch

    return torch.cuda.is_available()


@pytest.mark.slow
def test_track_bad_inputs_exit_2(walk_32_frames, tmp_path):
    root = str(walk_32_frames.root)
    np.savez(tmp_path / "bad_init.npz", poses=np.zeros((2, 31)))
    cases = [
        (["--views", "0,9"], "out of range"),
        (["--views", "a,b"], "comma-separated"),
        (["--frames", "99"], "past the end of the sequence"),
        (["--init", str(tmp_path / "bad_init.npz")], "bad_init.npz: poses must have shape T x 40"),
        (["--init", str(tmp_path / "missing.npz")], "cannot read initial poses"),
        (["--prior", "hmm"], "invalid choice"),
        (["--prior", "gpdm"], "needs a model file"),
        (["--device", "gpu"], "unknown device 'gpu'"),
    ] + ([] if torch_has_cuda() else [(["--device", "cuda"], "torch finds no CUDA device")])
    for extra, expected in cases:
        args = ["track", root, "--out", str(tmp_path / "o"), "--particles", "50", "--frames", "4"]
        if "--prior" not in extra:
            args += ["--prior", "zero-velocity"]
        r = subprocess.run([sys.executable, "-m", "tracker", *args, *extra], capture_output=True, text=True)
        err = r.stderr.strip().splitlines()[-1] if r.stderr.strip() else ""
        assert r.returncode == 2 and expected in err and "Traceback" not in r.stderr, (extra, r.stderr[-300:])


@pytest.mark.slow
def test_ctrl_c_saves_a_checkpoint_and_resume_gives_the_uninterrupted_result(walk_32_frames, tmp_path):
    import signal
    import time

    # 400 particles: slow enough per frame that the run cannot finish between the first checkpoint and the
    # signal even when this process is starved on a busy machine (150 did, once, under a benchmark's load).
    args = ["track", str(walk_32_frames.root), "--prior", "constant-velocity", "--particles", "400",
            "--frames", "24", "--seed", "5", "--checkpoint-every", "2"]
    assert main([*args, "--out", str(tmp_path / "whole")]) == 0
    out = tmp_path / "cut"
    # The child starts with Ctrl-C's default action whatever this process inherited or was left with (a SIGINT
    # ignored here would be ignored by the child, which then tracks to the end; the whole suite once did that).
    proc = subprocess.Popen([sys.executable, "-m", "tracker", *args, "--out", str(out)],
                            stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True,
                            preexec_fn=lambda: signal.signal(signal.SIGINT, signal.SIG_DFL))
    deadline = time.time() + 120
    while not (out / "checkpoint.npz").exists() and time.time() < deadline:
        time.sleep(0.01)
    proc.send_signal(signal.SIGINT)
    _, err = proc.communicate(timeout=120)
    assert proc.returncode == 130 and "resume with: pose-tracker track --resume" in err, err[-500:]
    assert "Traceback" not in err
    partial = json.loads((out / "result.json").read_text())
    assert partial["complete"] is False and partial["frames"] == 24 and 0 < partial["frames_tracked"] < 22
    r = subprocess.run([sys.executable, "-m", "tracker", "track", "--resume", str(out)], capture_output=True,
                       text=True)
    assert r.returncode == 0, r.stderr[-500:]
    with np.load(out / "estimates.npz") as a, np.load(tmp_path / "whole" / "estimates.npz") as b:
        assert np.array_equal(a["poses"], b["poses"]) and np.array_equal(a["best_poses"], b["best_poses"])
    resumed = json.loads((out / "result.json").read_text())
    assert resumed["metrics"] == json.loads((tmp_path / "whole" / "result.json").read_text())["metrics"]
    assert resumed["complete"] is True
    assert not (out / "checkpoint.npz").exists()
    r = subprocess.run([sys.executable, "-m", "tracker", "track", "--resume", str(out)], capture_output=True,
                       text=True)
    assert r.returncode == 2 and "no interrupted run to resume" in r.stderr


def test_a_checkpoint_written_before_frames_recorded_their_wall_time_resumes(tmp_path):
    """Checkpoints of interrupted runs from before ``wall_seconds`` existed still resume: a frame's wall time
    was then the sum of its stages."""
    from tracker.app.checkpoint import load_checkpoint, save_checkpoint
    from tracker.engine.filter import FilterState
    from tracker.engine.recording import DEFAULT_RECORD, Recording
    from tracker.engine.weights import LogWeights

    old = Recording([n for n in DEFAULT_RECORD if n != "wall_seconds"])
    old.values.update({"mean_poses": [np.zeros(3)] * 2, "best_poses": [np.zeros(3)] * 2, "ess": [5.0, 6.0],
                       "resampled": [True, False], "recovered": [False, False], "load_seconds": [0.01, 0.02],
                       "observe_seconds": [0.0, 0.0], "filter_seconds": [0.03, 0.04], "prior_labels": ["a", "a"]})
    state = FilterState(np.zeros((4, 1, 3)), None, LogWeights.uniform(4), np.zeros((1, 3)), 1, 2)
    rng = np.random.default_rng(0)
    save_checkpoint(tmp_path / "c.npz", state, old, rng.bit_generator.state, {"x": 1})
    recording = Recording(DEFAULT_RECORD)
    restored, _ = load_checkpoint(tmp_path / "c.npz", {"x": 1}, recording, rng)
    assert restored.tracked == 2 and np.allclose(recording.values["wall_seconds"], [0.04, 0.06])


def test_a_nested_prior_state_survives_a_checkpoint(tmp_path):
    """An ensemble's state holds each model's state as a dict (with None for a model without one); a
    checkpoint gives it back as it was (it was refused as 'not an intact .npz file' before)."""
    from tracker.app.checkpoint import load_checkpoint, save_checkpoint
    from tracker.engine.filter import FilterState
    from tracker.engine.recording import DEFAULT_RECORD, Recording
    from tracker.engine.weights import LogWeights

    prior_state = {"component": np.array([0, 1, 0, 1]), "arrived": np.ones(4, bool),
                   "model_0": {"step": np.ones((4, 3)), "pace": np.zeros(4)},
                   "model_1": {"step": np.full((4, 3), 2.0), "height_offset": np.arange(4.0)}, "model_2": None}
    state = FilterState(np.zeros((4, 1, 3)), prior_state, LogWeights.uniform(4), np.zeros((1, 3)), 1, 0)
    rng = np.random.default_rng(0)
    save_checkpoint(tmp_path / "c.npz", state, Recording(DEFAULT_RECORD), rng.bit_generator.state, {"x": 1})
    restored, _ = load_checkpoint(tmp_path / "c.npz", {"x": 1}, Recording(DEFAULT_RECORD), rng)
    got = restored.prior_state
    assert set(got) == set(prior_state) and got["model_2"] is None
    assert all(np.array_equal(got[k], prior_state[k]) for k in ("component", "arrived"))
    for k in ("model_0", "model_1"):
        assert set(got[k]) == set(prior_state[k])
        assert all(np.array_equal(got[k][n], prior_state[k][n]) for n in prior_state[k])


def test_the_likelihood_scores_the_same_on_several_threads(walk_32_frames, monkeypatch):
    """Blocks of particles shared among threads give the one-thread scores exactly; the registered likelihood
    gets the run's threads (tracker.set_threads), and a thread count that is not a positive integer is refused."""
    import threading

    import tracker.app.threads as threads
    from tracker.app.api import build_likelihood
    from tracker.core.errors import InputError

    seq = walk_32_frames
    truth = seq.groundtruth.poses[7]
    poses = truth + np.random.default_rng(0).normal(0, 0.05, (1100, truth.size))  # 6 blocks, the last short
    poses[3, seq.model.dof_index("left_knee_flexion")] = -1.0  # outside the limits
    config = EdgeSilhouetteConfig(bidirectional=True)
    one = EdgeSilhouetteLikelihood(seq.model, seq.rig, config).prepare(seq.frame(7, range(4))).terms(poses)
    shared = EdgeSilhouetteLikelihood(seq.model, seq.rig, config, threads=3)
    workers = set()
    block_costs = shared._compiled_block_costs
    together = threading.Barrier(3, timeout=20)  # the first three blocks are scored by three threads at once

    def recorded(*args):
        if len(workers) < 3:
            workers.add(threading.current_thread().name)
            together.wait()
        return block_costs(*args)

    monkeypatch.setattr(shared, "_compiled_block_costs", recorded)
    three = shared.prepare(seq.frame(7, range(4))).terms(poses)
    caller = threading.current_thread().name
    assert caller in workers and len(workers) == 3 and all(w.startswith("helper") for w in workers - {caller})
    for name in ("edge", "silhouette", "coverage", "log_likelihood"):
        assert np.array_equal(getattr(one, name), getattr(three, name)), name
    assert one.log_likelihood[3] == -np.inf
    for n in (1, 3):
        monkeypatch.setattr(threads, "_configured", n)
        assert build_likelihood("edge-silhouette", seq).threads == n
    for bad in (0, -1, 1.5, True, "2"):
        with pytest.raises(InputError, match="threads must be an integer of at least 1"):
            EdgeSilhouetteLikelihood(seq.model, seq.rig, threads=bad)


@pytest.mark.skipif(sys.platform != "linux", reason="forks a child process, as multiprocessing does on Linux")
def test_a_forked_child_scores_on_its_own_threads(walk_32_frames):
    """A process forked after the likelihood's threads started inherits their pool but not the threads: it must
    make its own, not wait for the parent's forever."""
    import multiprocessing

    seq = walk_32_frames
    scorer = EdgeSilhouetteLikelihood(seq.model, seq.rig, threads=2).prepare(seq.frame(7, range(4)))
    poses = seq.groundtruth.poses[7] + np.random.default_rng(0).normal(0, 0.05, (600, 40))
    expected = scorer(poses)
    context = multiprocessing.get_context("fork")
    queue = context.Queue()
    child = context.Process(target=lambda: queue.put(scorer(poses)))
    child.start()
    try:
        scores = queue.get(timeout=60)
    except Exception:
        child.kill()
        pytest.fail("the forked child did not finish scoring within 60 s")
    child.join(10)
    np.testing.assert_array_equal(scores, expected)


def test_a_block_that_fails_on_any_thread_stops_the_others_and_is_raised():
    import time

    from tracker.core.workers import share

    blocks = [slice(k, k + 1) for k in range(200)]
    for failing in (0, 57):  # the first block (this thread's) and one a helper takes
        scored = []

        def score(block):
            if block.start == failing:
                raise RuntimeError(f"block {failing}")
            time.sleep(0.001)  # a block's work (it releases the GIL, as scoring does)
            scored.append(block.start)

        with pytest.raises(RuntimeError, match=f"block {failing}"):
            share(score, blocks, threads=3)
        assert len(scored) < len(blocks) - 1  # the others stopped early


def test_the_track_progress_bar_counts_the_tracked_frames(walk_32_frames, tmp_path, capsys, monkeypatch):
    from tracker.app import console

    monkeypatch.setattr(console, "on_terminal", lambda: True)  # bars are drawn on a terminal only
    assert main(["track", str(walk_32_frames.root), "--prior", "zero-velocity", "--particles", "50",
                 "--frames", "6", "--out", str(tmp_path / "run")]) == 0
    err = capsys.readouterr().err
    assert "4/4" in err and "/6" not in err  # two of the six frames are known, not tracked
    assert "1/4 [00:00<?, ?frame/s" in err  # no rate from the first frame alone

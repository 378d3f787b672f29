"""The public API, the registries (a prior and a likelihood defined here, outside the package), the quick
start, and regressions found while building them."""
import json
import subprocess
import sys
import textwrap
from pathlib import Path

import numpy as np
import pytest

import tracker
from tracker.app.cli import main

REPO = Path(__file__).resolve().parents[2]


class DriftPrior(tracker.MotionPrior):
    """A toy first-order prior: every particle moves by a fixed root step plus small Gaussian noise."""

    order = 1
    name = "test-drift"

    def __init__(self, step_mm: float, std: np.ndarray):
        self.step_mm, self.std = step_mm, std

    def sample(self, history, available, state, rng):
        last = history[:, -1].copy()
        last[:, 0] += self.step_mm
        return last + rng.standard_normal(last.shape) * self.std, state

    def diffusion_std(self):
        return self.std

    def settings(self):
        return {"step_mm": self.step_mm}


@tracker.register_prior("test-drift", summary="toy prior defined in a test",
                        options=(tracker.Option("drift_mm", float, 0.0, "root step per frame (mm)"),))
def build_drift(context, model_files, options):
    return DriftPrior(options["drift_mm"], context.step_std())


def test_registries_list_builtins_and_plugins():
    assert {"zero-velocity", "constant-velocity", "crbm", "gpdm", "test-drift"} <= set(tracker.available_priors())
    assert "edge-silhouette" in tracker.available_likelihoods()


def test_prior_defined_outside_the_package_tracks_through_api_and_cli(walk_32_frames, tmp_path):
    seq = walk_32_frames
    res = tracker.track(seq, "test-drift", drift_mm=1.0, particles=100, frames=6, seed=2)
    assert res.settings["prior"] == "test-drift" and res.settings["prior_settings"] == {"step_mm": 1.0}
    assert len(res.errors) == 4 and res.mean_error < 100
    res.save(tmp_path / "api")
    assert main(["track", str(seq.root), "--prior", "test-drift", "--drift-mm", "1", "--particles", "100",
                 "--frames", "6", "--seed", "2", "--out", str(tmp_path / "cli")]) == 0
    api = json.loads((tmp_path / "api" / "result.json").read_text())
    cli = json.loads((tmp_path / "cli" / "result.json").read_text())
    assert api["metrics"] == cli["metrics"]  # one implementation behind both
    assert api["invocation"]["function"] == "tracker.track" and api["invocation"]["arguments"]["drift_mm"] == 1.0
    assert cli["invocation"]["argv"][:3] == ["pose-tracker", "track", str(seq.root)]
    assert {k for k in api if k != "seconds_per_frame"} == {k for k in cli if k != "seconds_per_frame"}


@pytest.mark.slow
def test_plugin_file_through_the_command_line(walk_32_frames, tmp_path):
    plugin = tmp_path / "my_prior.py"
    plugin.write_text(textwrap.dedent('''
        import numpy as np
        import tracker

        class Still(tracker.MotionPrior):
            order, name = 1, "still"
            def sample(self, history, available, state, rng):
                return history[:, -1] + 0.5 * rng.standard_normal(history[:, -1].shape), state
            def diffusion_std(self):
                return np.full(40, 0.5)

        @tracker.register_prior("still", summary="a plugin file's prior")
        def build(context, model_files, options):
            return Still()
    '''))
    r = subprocess.run([sys.executable, "-m", "tracker", "--plugin", str(plugin), "track", str(walk_32_frames.root),
                        "--prior", "still", "--particles", "50", "--frames", "4", "--out", str(tmp_path / "o")],
                       capture_output=True, text=True)
    assert r.returncode == 0, r.stderr[-500:]
    assert json.loads((tmp_path / "o" / "result.json").read_text())["prior"] == "still"
    r = subprocess.run([sys.executable, "-m", "tracker", "--plugin", str(tmp_path / "nope.py"), "--help"],
                       capture_output=True, text=True)
    assert r.returncode == 2 and "plugin file not found" in r.stderr and "Traceback" not in r.stderr


def test_likelihood_defined_outside_the_package(walk_32_frames):
    class CentreLikelihood(tracker.Likelihood):
        """Scores the root's distance to the ground truth of the frame (a toy oracle)."""

        name = "test-oracle"

        def prepare(self, frame):
            target = walk_32_frames.groundtruth.poses[frame.index, :3]

            class Bound(tracker.FrameLikelihood):
                def __call__(self, poses):
                    return -np.sum((poses[:, :3] - target) ** 2, axis=1) / 50.0 ** 2
            return Bound()

    tracker.register_likelihood("test-oracle")(lambda context, options: CentreLikelihood())
    res = tracker.track(walk_32_frames, "zero-velocity", likelihood="test-oracle", particles=200, frames=8, seed=0)
    assert res.settings["likelihood"] == "test-oracle" and np.all(np.isfinite(res.errors))


def test_options_are_checked_per_plugin(walk_32_frames, tmp_path):
    with pytest.raises(tracker.InputError, match="takes no option 'gibbs_steps'"):
        tracker.build_prior("zero-velocity", walk_32_frames, gibbs_steps=3)
    with pytest.raises(tracker.InputError, match="must be at least 1"):
        tracker.build_prior("crbm", walk_32_frames, ["m.pt"], gibbs_steps=0)
    with pytest.raises(tracker.InputError, match="unknown prior 'nope'"):
        tracker.build_prior("nope", walk_32_frames)
    r = subprocess.run([sys.executable, "-m", "tracker", "track", str(walk_32_frames.root), "--prior",
                        "zero-velocity", "--gibbs-steps", "3", "--out", str(tmp_path / "o")],
                       capture_output=True, text=True)
    assert r.returncode == 2 and "--gibbs-steps does not apply to prior zero-velocity" in r.stderr


def test_records_chosen_by_the_caller(walk_32_frames):
    res = tracker.track(walk_32_frames, "zero-velocity", particles=60, frames=5, seed=1,
                        record=("ess", "particles", "weights"))
    assert res.records["particles"].shape == (3, 60, 40) and res.records["weights"].shape == (3, 60)
    assert res.poses.shape == (5, 40) and res.ess.shape == (3,)


def test_track_anneals_with_three_layers_unless_told_otherwise(walk_32_frames):
    from tracker.app.api import TRACK_ANNEALING_LAYERS

    default = tracker.track(walk_32_frames, "zero-velocity", particles=50, frames=4, seed=3)
    three = tracker.track(walk_32_frames, "zero-velocity", particles=50, frames=4, seed=3, annealing_layers=3)
    one = tracker.track(walk_32_frames, "zero-velocity", particles=50, frames=4, seed=3, annealing_layers=1)
    assert TRACK_ANNEALING_LAYERS == 3 and default.settings["annealing_layers"] == 3
    assert np.array_equal(default.poses, three.poses) and not np.array_equal(default.poses, one.poses)
    assert one.settings["annealing_layers"] == 1


def test_seed_sequences_and_generators_are_accepted(walk_32_frames):
    a = tracker.track(walk_32_frames, "zero-velocity", particles=50, frames=4,
                      seed=np.random.SeedSequence(5).spawn(2)[1])
    b = tracker.track(walk_32_frames, "zero-velocity", particles=50, frames=4,
                      seed=np.random.default_rng(np.random.SeedSequence(5).spawn(2)[1]))
    assert np.array_equal(a.poses, b.poses) and a.settings["seed"]["spawn_key"] == [1]
    for seed in (-1, 2 ** 63):  # the bounds the schema declares, the same as on the command line
        with pytest.raises(tracker.InputError, match=f"seed must be at least 0 and at most {2 ** 63 - 1}, got"):
            tracker.track(walk_32_frames, "zero-velocity", frames=4, seed=seed)


def test_new_observations_are_never_scored_against_old_cost_maps(walk_32_frames):
    """Regression: cost maps were cached by id(obs), so a new object at a reused address kept old maps."""
    from likelihoods.edge_silhouette import EdgeSilhouetteLikelihood
    from likelihoods.observations import Observations

    seq = walk_32_frames
    lik = EdgeSilhouetteLikelihood(seq.model, seq.rig)
    shape = (4, seq.rig[0].height, seq.rig[0].width)
    pose = seq.groundtruth.poses[3][None]
    scores = []
    for value in (1.0, 0.0, 1.0):
        obs = Observations(np.full(shape, value, np.float32), np.full(shape, value, np.float32))
        scores.append(float(lik.prepare_observations(obs)(pose)[0]))
        del obs  # frees the address for the next object
    assert scores[0] == scores[2] and scores[1] < scores[0] - 100.0


@pytest.mark.slow
def test_drawing_leaves_the_matplotlib_backend_alone(tmp_path):
    code = ("import matplotlib; matplotlib.use('svg'); from tracker.app.visualize import error_plot; "
            "import numpy as np; error_plot(r'%s', {'a': (np.arange(3), np.ones(3))}, 't'); "
            "print(matplotlib.get_backend())" % (tmp_path / "p.png"))
    r = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True)
    assert r.returncode == 0 and r.stdout.strip() == "svg", r.stderr[-300:]
    assert (tmp_path / "p.png").stat().st_size > 1000


@pytest.mark.slow
def test_quick_start_runs(tmp_path):
    r = subprocess.run([sys.executable, str(REPO / "examples" / "quickstart.py"), "--out", str(tmp_path),
                        "--frames", "6", "--particles", "60", "--seeds", "2", "--epochs", "10"],
                       capture_output=True, text=True, cwd=tmp_path)
    assert r.returncode == 0, r.stderr[-500:]
    lines = r.stdout.strip().splitlines()
    assert lines[0].strip().startswith("zero-velocity:") and lines[1].strip().startswith("crbm:")
    assert (tmp_path / "crbm" / "result.json").exists()


@pytest.mark.slow
def test_plugins_do_not_pull_in_the_application_layer():
    code = ("import sys, importlib, pkgutil\n"
            "for pkg in ('priors', 'likelihoods', 'data_tools'):\n"
            "    p = importlib.import_module(pkg)\n"
            "    for m in pkgutil.iter_modules(p.__path__):\n"
            "        importlib.import_module(pkg + '.' + m.name)\n"
            "print(sorted(m for m in sys.modules if m.startswith('tracker.app')))")
    r = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True)
    assert r.returncode == 0 and r.stdout.strip() == "[]", (r.stdout, r.stderr[-300:])


def test_a_plugin_option_clashing_with_a_command_flag_is_refused(tmp_path):
    plugin = tmp_path / "clash.py"
    plugin.write_text(textwrap.dedent('''
        import tracker

        @tracker.register_prior("clashing", options=(tracker.Option("seed", int, 0, "a clash"),))
        def build_clashing(context, model_files, options):
            raise AssertionError("never built")
    '''))
    r = subprocess.run([sys.executable, "-m", "tracker", "--plugin", str(plugin), "track", "--help"],
                       capture_output=True, text=True)
    assert r.returncode == 2 and "clashes with a flag" in r.stderr and "Traceback" not in r.stderr


def test_seconds_per_frame_is_measured_whatever_is_recorded(synthetic_walk, random_walk_std):
    """A run that records only some quantities still reports its wall time per frame."""
    import tracker

    tracker.set_threads(1)
    for record in (("ess", "particles", "weights"), {"ess": lambda step: step.ess}):
        result = tracker.track(synthetic_walk.root, "zero-velocity", particles=50, frames=4, seed=0, annealing_layers=1,
                               step_std=random_walk_std, record=record)
        assert result.seconds_per_frame > 0 and result.to_dict()["seconds_per_frame"] > 0


@pytest.mark.slow
def test_track_takes_the_model_train_returns_and_the_options_of_prior_and_likelihood(synthetic_walk, tmp_path):
    """The model object and its file track to the same numbers; options go to the plugin that declares them."""
    skeleton, walks = tracker.sample_walks()
    model = tracker.train("crbm", walks[:1], skeletons=[skeleton], order=1, epochs=2, hidden=10, seed=0)
    model.save(tmp_path / "m.pt")
    settings = dict(particles=40, frames=4, seed=1, annealing_layers=1, gibbs_steps=2, sharpness=30.0)
    from_object = tracker.track(synthetic_walk.root, "crbm", models=[model], **settings)
    from_file = tracker.track(synthetic_walk.root, "crbm", models=[tmp_path / "m.pt"], **settings)
    assert np.array_equal(from_object.poses, from_file.poses)
    assert from_object.settings["prior_models"] == ["CRBMModel (in memory)"]
    assert from_object.settings["prior_settings"]["gibbs_steps"] == 2
    assert from_object.settings["likelihood_settings"]["sharpness"] == 30.0
    # every declared option, given or default, as result.json records it
    assert from_object.settings["prior_options"] == {"gibbs_steps": 2, "root_noise": 5.0, "pace_spread": None,
                                                     "pace_drift": None, "height_spread": None, "height_drift": 0.0,
                                                     "posture_gain": None}
    assert from_object.to_dict()["likelihood_options"] == {"sharpness": 30.0, "bidirectional": True,
                                                            "ground_std": None, "root_height_std": None}
    with pytest.raises(tracker.InputError, match="takes no option 'order'.*prior crbm: gibbs_steps"):
        tracker.track(synthetic_walk.root, "crbm", models=[model], order=3)
    with pytest.raises(tracker.InputError, match="a CRBM model is a model file or a trained CRBM model"):
        tracker.track(synthetic_walk.root, "crbm", models=[42])

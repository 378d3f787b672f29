"""The SIR filter against a Kalman filter, resampling schemes, annealing exponent, recovery, determinism."""
import numpy as np
import pytest

from tracker.engine.filter import FilterConfig, ParticleFilter, choose_beta
from tracker.engine.likelihood import Frame, FrameLikelihood, Likelihood
from tracker.engine.prior import MotionPrior
from tracker.engine.resampling import SCHEMES
from tracker.engine.weights import LogWeights, effective_sample_size


class FunctionLikelihood(Likelihood):
    """Frame k is scored by ``functions[k]`` (poses P x D -> log-likelihoods (P,))."""

    def __init__(self, functions):
        self.functions = functions

    def prepare(self, frame: Frame) -> FrameLikelihood:
        f = self.functions[frame.index]

        class Bound(FrameLikelihood):
            def __call__(self, poses):
                return f(poses)
        return Bound()


def run_filter(prior, functions, config, rng, known, **kw):
    pf = ParticleFilter(prior, FunctionLikelihood(functions), config, rng)
    return pf.run(known, [Frame(k, ()) for k in range(len(functions))], **kw)


class LinearGaussianPrior(MotionPrior):
    """x_t = A x_{t-1} + N(0, Q), Q diagonal."""

    order = 1
    name = "linear-gaussian"

    def __init__(self, A: np.ndarray, q: np.ndarray):
        self.A, self.q = A, q

    def sample(self, history, available, state, rng):
        last = history[:, -1]
        return last @ self.A.T + rng.standard_normal(last.shape) * np.sqrt(self.q), state

    def diffusion_std(self):
        return np.sqrt(self.q)


def test_sir_matches_kalman_filter():
    rng = np.random.default_rng(7)
    A = np.array([[0.95, 0.1], [0.0, 0.9]])
    q = np.array([0.3, 0.2])
    r = np.array([0.5, 0.8])
    T, x0 = 25, np.array([1.0, -1.0])
    xs, ys = [], []
    x = x0
    for _ in range(T):
        x = A @ x + rng.standard_normal(2) * np.sqrt(q)
        xs.append(x)
        ys.append(x + rng.standard_normal(2) * np.sqrt(r))
    # Kalman filter from the known x0 (zero initial covariance).
    m, Pc = x0, np.zeros((2, 2))
    kf_means, kf_vars = [], []
    for y in ys:
        m, Pc = A @ m, A @ Pc @ A.T + np.diag(q)
        K = Pc @ np.linalg.inv(Pc + np.diag(r))
        m, Pc = m + K @ (y - m), (np.eye(2) - K) @ Pc
        kf_means.append(m)
        kf_vars.append(np.diag(Pc))
    lls = [lambda p, y=y: -0.5 * np.sum((p - y) ** 2 / r, axis=1) for y in ys]
    res = run_filter(LinearGaussianPrior(A, q), lls, FilterConfig(n_particles=4000), np.random.default_rng(1),
                     x0[None])
    mc_std = np.sqrt(np.array(kf_vars) / res["ess"][:, None])  # Monte Carlo error of a weighted mean
    z = (res["mean_poses"] - np.array(kf_means)) / mc_std
    assert np.all(np.abs(z) < 5.0)
    assert abs(z.mean()) < 1.0 and np.sqrt(np.mean(z ** 2)) < 2.0
    assert res["resampled"].any() and not res["resampled"].all()  # ESS-triggered, weights carried in between


@pytest.mark.parametrize("scheme", sorted(SCHEMES))
def test_resampling_is_unbiased(scheme):
    rng = np.random.default_rng(3)
    w = np.array([0.31, 0.02, 0.17, 0.0, 0.25, 0.05, 0.2])
    P, reps = len(w), 4000
    counts = np.zeros(P)
    for _ in range(reps):
        idx = SCHEMES[scheme](w, rng)
        assert idx.shape == (P,) and np.all(np.diff(idx) >= 0)
        counts += np.bincount(idx, minlength=P)
    mean = counts / reps
    bound = 5 * np.sqrt(P * w * (1 - w) / reps) + 1e-9  # multinomial variance bounds the others
    assert np.all(np.abs(mean - P * w) <= bound), (mean, P * w)
    assert mean[3] == 0.0


def test_effective_sample_size_and_beta():
    assert effective_sample_size(np.full(10, 0.1)) == pytest.approx(10)
    assert effective_sample_size(np.eye(5)[2]) == pytest.approx(1)
    ll = np.random.default_rng(0).normal(0, 5, 1000)
    beta = choose_beta(ll, 0.3)
    w = np.exp(beta * (ll - ll.max()))
    assert effective_sample_size(w / w.sum()) == pytest.approx(300, rel=0.02)


class StepPrior(LinearGaussianPrior):
    def __init__(self):
        super().__init__(np.eye(1), np.array([0.01]))


def test_all_weights_minus_inf_recovers_without_nan():
    lls = [lambda p: -p[:, 0] ** 2, lambda p: np.full(len(p), -np.inf), lambda p: -p[:, 0] ** 2]
    res = run_filter(StepPrior(), lls, FilterConfig(n_particles=200), np.random.default_rng(0), np.zeros((1, 1)))
    assert list(np.flatnonzero(res["recovered"])) == [1] and np.all(np.isfinite(res["mean_poses"]))


def test_annealed_filter_concentrates_particles():
    lls = [lambda p: -0.5 * np.sum((p - 2.0) ** 2, axis=1) / 0.01] * 3
    plain = run_filter(LinearGaussianPrior(np.eye(2), np.array([1.0, 1.0])), lls, FilterConfig(n_particles=300),
                       np.random.default_rng(0), np.zeros((1, 2)))
    annealed = run_filter(LinearGaussianPrior(np.eye(2), np.array([1.0, 1.0])), lls,
                          FilterConfig(n_particles=300, annealing_layers=5), np.random.default_rng(0),
                          np.zeros((1, 2)))
    assert np.all(annealed["resampled"])
    err = lambda r: np.abs(r["mean_poses"][-1] - 2.0).max()  # noqa: E731
    assert err(annealed) < 0.1 and err(annealed) <= err(plain) + 0.05


def test_same_seed_same_result_and_seed_matters():
    def run(seed):
        return run_filter(StepPrior(), [lambda p: -(p[:, 0] - 0.1) ** 2 / 0.001] * 5, FilterConfig(n_particles=100),
                          np.random.default_rng(seed), np.zeros((1, 1)))["mean_poses"]
    assert np.array_equal(run(4), run(4)) and not np.array_equal(run(4), run(5))


def test_log_weights_object():
    w = LogWeights(np.array([0.0, np.log(3.0), -np.inf]))
    assert np.allclose(w.normalised, [0.25, 0.75, 0.0]) and w.ess == pytest.approx(1 / (0.25 ** 2 + 0.75 ** 2))
    assert w.any_finite and not LogWeights(np.full(3, -np.inf)).any_finite
    assert np.allclose(w.add(np.log([3.0, 1.0, 1.0])).normalised, [0.5, 0.5, 0.0])
    assert np.allclose(w.renormalised().log_w[:2], np.log([0.25, 0.75]))


def test_caller_chooses_what_is_recorded_and_sees_particles():
    seen = []
    lls = [lambda p: -(p[:, 0] - 0.1) ** 2 / 0.01] * 4
    res = run_filter(StepPrior(), lls, FilterConfig(n_particles=50), np.random.default_rng(0), np.zeros((1, 1)),
                     record=("ess", "particles", "weights"),
                     on_frame=lambda step: seen.append((step.index, step.particles.shape, step.weights.ess)))
    assert set(res) == {"ess", "particles", "weights"}
    assert res["particles"].shape == (4, 50, 1) and np.allclose(res["weights"].sum(axis=1), 1.0)
    assert [s[0] for s in seen] == [0, 1, 2, 3] and seen[0][1] == (50, 1)
    assert np.allclose([s[2] for s in seen], res["ess"])
    custom = run_filter(StepPrior(), lls, FilterConfig(n_particles=50), np.random.default_rng(0), np.zeros((1, 1)),
                        record={"spread": lambda step: float(step.particles.std())})
    assert custom["spread"].shape == (4,)


def test_step_by_step_equals_run():
    lls = [lambda p: -(p[:, 0] - 0.1) ** 2 / 0.01] * 4
    whole = run_filter(StepPrior(), lls, FilterConfig(n_particles=60), np.random.default_rng(9), np.zeros((1, 1)))
    pf = ParticleFilter(StepPrior(), FunctionLikelihood(lls), FilterConfig(n_particles=60), np.random.default_rng(9))
    state, means = pf.start(np.zeros((1, 1))), []
    for k in range(4):
        state, step = pf.step(state, Frame(k, ()))
        means.append(step.mean)
    assert np.array_equal(np.array(means), whole["mean_poses"]) and state.tracked == 4


def test_frames_prepared_ahead_in_threads_give_the_same_result():
    prior = LinearGaussianPrior(np.eye(2), np.full(2, 0.1))
    functions = [lambda x, k=k: -0.5 * np.sum((x - 0.1 * k) ** 2, axis=1) for k in range(8)]
    config = FilterConfig(n_particles=300, annealing_layers=2)
    serial = run_filter(prior, functions, config, np.random.default_rng(3), np.zeros((1, 2)))
    for workers in (1, 3):  # (up to 3 frames ahead)
        ahead = run_filter(prior, functions, config, np.random.default_rng(3), np.zeros((1, 2)), workers=workers)
        assert np.array_equal(ahead["mean_poses"], serial["mean_poses"])
        assert np.all(ahead["observe_seconds"] == 0.0)  # prepared in the background: the wait counts as load


def test_a_frame_that_fails_to_read_ahead_stops_the_run_where_it_is_due():
    from tracker.core.errors import InputError

    def frames():
        for k in range(6):
            if k == 4:
                raise InputError("cannot read image: truncated PNG", f"frame{k}.png")
            yield Frame(k, ())

    prior = LinearGaussianPrior(np.eye(2), np.full(2, 0.1))
    functions = [lambda x: -0.5 * np.sum(x ** 2, axis=1)] * 6
    for workers in (0, 1, 2):
        seen = []
        pf = ParticleFilter(prior, FunctionLikelihood(functions), FilterConfig(n_particles=50),
                            np.random.default_rng(0))
        with pytest.raises(InputError) as err:
            pf.run(np.zeros((1, 2)), frames(), on_frame=lambda step: seen.append(step.frame), workers=workers)
        assert seen == [0, 1, 2, 3]
        assert str(err.value).splitlines() == [str(err.value)] and "truncated PNG" in str(err.value)


def test_with_workers_the_filter_steps_beside_the_reading_thread():
    """With workers, frames are read (and images decoded) in the calling thread while another thread filters;
    the callbacks run in the calling thread, between steps."""
    import threading

    caller = threading.current_thread().name
    seen = {"read": set(), "likelihood": set(), "on_frame": set()}

    def frames():
        for k in range(5):
            seen["read"].add(threading.current_thread().name)
            yield Frame(k, ())

    def score(x):
        seen["likelihood"].add(threading.current_thread().name)
        return -0.5 * np.sum(x ** 2, axis=1)

    prior = LinearGaussianPrior(np.eye(2), np.full(2, 0.1))
    pf = ParticleFilter(prior, FunctionLikelihood([score] * 5), FilterConfig(n_particles=50), np.random.default_rng(0))
    pf.run(np.zeros((1, 2)), frames(), on_frame=lambda step: seen["on_frame"].add(threading.current_thread().name),
           workers=1)
    assert seen["read"] == {caller} and seen["on_frame"] == {caller}
    assert seen["likelihood"] and caller not in seen["likelihood"]


def test_a_step_that_fails_in_the_filter_thread_is_raised_after_the_frames_before_it():
    from tracker.core.errors import InputError

    def score(k):
        def f(x):
            if k == 3:
                raise InputError("the likelihood refused frame 3")
            return -0.5 * np.sum(x ** 2, axis=1)
        return f

    prior = LinearGaussianPrior(np.eye(2), np.full(2, 0.1))
    for workers in (0, 1):
        seen = []
        pf = ParticleFilter(prior, FunctionLikelihood([score(k) for k in range(6)]), FilterConfig(n_particles=50),
                            np.random.default_rng(0))
        with pytest.raises(InputError, match="refused frame 3"):
            pf.run(np.zeros((1, 2)), [Frame(k, ()) for k in range(6)],
                   on_frame=lambda step: seen.append(step.frame), workers=workers)
        assert seen == [0, 1, 2]


def test_each_frame_records_the_wall_time_it_added():
    """``wall_seconds``: with the stages in one thread about their sum; with reading and filtering overlapped,
    less than their sum (each frame's reading sleeps 20 ms and its filter step 20 ms)."""
    import time

    def frames():
        for k in range(6):
            time.sleep(0.02)
            yield Frame(k, ())

    def slow(x):
        time.sleep(0.02)
        return -0.5 * np.sum(x ** 2, axis=1)

    prior = LinearGaussianPrior(np.eye(2), np.full(2, 0.1))
    walls = {}
    for workers in (0, 1):
        pf = ParticleFilter(prior, FunctionLikelihood([slow] * 6), FilterConfig(n_particles=50),
                            np.random.default_rng(0))
        r = pf.run(np.zeros((1, 2)), frames(), record=("wall_seconds", "load_seconds", "observe_seconds",
                                                        "filter_seconds"), workers=workers)
        stages = r["load_seconds"] + r["observe_seconds"] + r["filter_seconds"]
        walls[workers] = float(np.median(r["wall_seconds"]))
        if workers == 0:
            assert np.all(np.abs(r["wall_seconds"] - stages) < 0.01)
        else:
            assert np.median(r["wall_seconds"]) < 0.8 * np.median(stages)
    assert walls[1] < 0.8 * walls[0], walls


def test_numpy_blas_runs_on_one_thread_while_the_filter_runs_and_is_restored_after():
    """Preparing frames (here or ahead, in threads) and scoring them see one BLAS thread: a parallel BLAS call
    leaves its threads spinning on the cores the likelihood needs. The caller's setting comes back after."""
    from threadpoolctl import threadpool_info, threadpool_limits

    def blas_threads() -> set[int]:
        return {lib["num_threads"] for lib in threadpool_info() if lib["user_api"] == "blas"}

    seen = []

    class Probe(FunctionLikelihood):
        def prepare(self, frame):
            seen.append(blas_threads())
            return super().prepare(frame)

    def score(x):
        seen.append(blas_threads())
        return -0.5 * np.sum(x ** 2, axis=1)

    if not blas_threads():
        pytest.skip("numpy reports no BLAS library to threadpoolctl")
    prior = LinearGaussianPrior(np.eye(2), np.full(2, 0.1))
    with threadpool_limits(2, user_api="blas"):
        for workers in (0, 1, 3):
            seen.clear()
            pf = ParticleFilter(prior, Probe([score] * 4), FilterConfig(n_particles=50), np.random.default_rng(0))
            pf.run(np.zeros((1, 2)), [Frame(k, ()) for k in range(4)], workers=workers)
            assert len(seen) == 8 and all(s == {1} for s in seen), (workers, seen)
            assert blas_threads() == {2}


@pytest.mark.slow
def test_a_run_keeps_no_frame_s_particles_once_it_has_moved_on(walk_32_frames, random_walk_std):
    """What a run records of each frame (the estimates, timings, ...) holds none of that frame's particle
    arrays: memory grows with the frames by the recorded numbers only."""
    import gc
    import weakref

    from tracker import track

    refs, kept = [], []

    def on_frame(step, err) -> None:  # the particles of frames two or more back, still held by anything
        gc.collect()
        kept.append(sum(ref() is not None for ref in refs[:-1]))
        refs.append(weakref.ref(step.particles))

    track(walk_32_frames, "zero-velocity", particles=200, frames=20, seed=0, step_std=random_walk_std,
          on_frame=on_frame)
    assert len(kept) == 18 and max(kept) == 0

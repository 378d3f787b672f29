"""The demo (``pose-tracker demo``), a first run that needs no data of one's own: render a shipped walk of one
person (CMU subject 2), train a CRBM on another person's walks (subject 7), track with the zero-velocity prior,
the CRBM prior and the mixture of the two, say in one line what the comparison shows, and write the error plot
and an overlay video of the mixture's estimates -- all through the public API, as a user's script would.

The output folder is the demo's own: a second demo replaces the files an earlier one wrote there (so running it
twice just works), and a non-empty folder that holds no demo output is refused.

What it does and how long it took are log lines (:mod:`logging`, shown by the command line unless ``--quiet``);
the errors of each prior, the line saying what they show and the data's attribution are its results, printed to
stdout."""
from __future__ import annotations

import logging
from pathlib import Path

import numpy as np

from data_tools.samples import CMU_ATTRIBUTION, sample_walks
from tracker.app.api import TRACK_ANNEALING_LAYERS, load_clip, synthesize, track, train
from tracker.app.console import progress_bar
from tracker.app.tracking import metrics_line

log = logging.getLogger(__name__)


#: What marks a folder as an earlier demo's output (the first things the demo writes).
DEMO_FILES = ("sequence", "crbm1.pt")
#: The shipped CMU subjects: the priors learn from the first one's walks and track the second one's walk.
TRAIN_SUBJECT, TRACK_SUBJECT = 7, 2


#: How the comparison line names each prior.
PRIOR_LABELS = {"zero-velocity": "zero-velocity", "crbm": "the CRBM", "mixture": "the mixture"}


def _against(error_mm: float, baseline_mm: float) -> str:
    """How a mean error (mm) compares with a baseline's: ``1.25 times lower``, ``1.10 times higher`` or ``the
    same`` (to the 0.1 mm the errors are printed to)."""
    if round(error_mm, 1) == round(baseline_mm, 1):
        return "the same"
    ratio = max(error_mm, baseline_mm) / min(error_mm, baseline_mm)
    return f"{ratio:.2f} times {'lower' if error_mm < baseline_mm else 'higher'}"


def comparison_line(errors_mm: dict[str, float], tracked: str, trained_on: str) -> str:
    """One line saying what the demo's comparison shows, from the mean marker errors (mm) it just measured
    (``{"zero-velocity": ..., "crbm": ..., "mixture": ...}``): which prior tracked best, and each learned one's
    error against zero-velocity's, on a person (``tracked``) the CRBM never saw (it learned from ``trained_on``)."""
    baseline = errors_mm["zero-velocity"]
    best = min(errors_mm, key=errors_mm.get)
    learned = [f"{PRIOR_LABELS[name]} {error:.1f} mm ({_against(error, baseline)})"
               for name, error in errors_mm.items() if name != "zero-velocity"]
    return (f"What this shows: on {tracked}, a person the CRBM never saw (it learned from {trained_on}), "
            f"{PRIOR_LABELS[best]} tracked best; against zero-velocity's {baseline:.1f} mm: {', '.join(learned)}; "
            "one seed, one short clip: a sketch, not a benchmark.")


def run_demo(out: Path, frames: int = 90) -> int:
    from data_tools.files import check_output_folder
    from tracker.app.visualize import error_plot, overlay_frames, write_video

    out = check_output_folder(out, replaceable=DEMO_FILES)

    train_asf, train_walks = sample_walks(TRAIN_SUBJECT)
    test_asf, (test_walk,) = sample_walks(TRACK_SUBJECT)
    log.info(f"1/4 Rendering {frames} frames of CMU walk {test_walk.stem} (subject {TRACK_SUBJECT}) into 4 cameras "
             "(60 Hz, 640x480)")
    seq = synthesize(load_clip(test_walk, test_asf, fps=60.0), out / "sequence", frames=frames, overwrite=True,
                     progress=lambda it: progress_bar(it, desc="rendering", unit="frame"))
    clips = [load_clip(walk, train_asf, fps=60.0) for walk in train_walks]
    names = " and ".join(walk.stem for walk in train_walks)
    log.info(f"2/4 Training a first-order CRBM (150 hidden units, CD-10, 300 epochs) on {names} "
             f"(subject {TRAIN_SUBJECT}, another person)")
    crbm = train("crbm", clips, fps=60.0, seed=0, order=1, hidden=150, epochs=300)
    crbm.save(out / "crbm1.pt", overwrite=True)
    log.info(f"   {crbm.summary()} -> {out / 'crbm1.pt'}")
    log.info(f"3/4 Tracking with each prior, 1000 particles, {TRACK_ANNEALING_LAYERS} annealing layers (the default), "
             "4 views, seed 0")
    runs, errors = {}, {}
    for name, models in (("zero-velocity", ()), ("crbm", (out / "crbm1.pt",)), ("mixture", (out / "crbm1.pt",))):
        with progress_bar(total=frames - 2, desc=name, unit="frame") as bar:
            runs[name] = track(seq, name, models=models, particles=1000, seed=0, train_mocap=train_walks,
                               on_frame=lambda step, e: (bar.update(1), bar.set_postfix(mpjpe_abs=f"{e:.0f} mm")))
        res = runs[name].save(out / f"track_{name}", overwrite=True)
        print(f"{name}, {res['frames_tracked']} frames tracked: {metrics_line(res['metrics'])}")
        errors[name] = res["metrics"]["mpjpe_abs"]["mean"]
        log.info(f"   {runs[name].seconds_per_frame:.3f} s per frame -> {out / f'track_{name}'}")
    print(comparison_line(errors, f"CMU subject {TRACK_SUBJECT}", f"subject {TRAIN_SUBJECT}'s walks {names}"))
    log.info("4/4 Writing the error plot and the overlay video (the mixture's estimates)")
    curves = {name: (np.arange(r.first_tracked, len(r.poses)), r.errors) for name, r in runs.items()}
    error_plot(out / "error_per_frame.png", curves,
               f"Tracking CMU {test_walk.stem} (CRBM trained on subject {TRAIN_SUBJECT}), 4 views, 1000 particles, "
               f"{TRACK_ANNEALING_LAYERS} annealing layers")
    shown = runs["mixture"]
    write_video(out / "overlay.mp4", overlay_frames(seq, shown.poses, list(range(seq.n_views)), shown.errors,
                                                    shown.first_tracked, estimate_name="mixture"), seq.fps)
    log.info(f"   {out / 'error_per_frame.png'}, {out / 'overlay.mp4'}")
    print(CMU_ATTRIBUTION)
    return 0

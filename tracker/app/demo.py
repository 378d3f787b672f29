"""The demo (``pose-tracker demo``), a first run that needs no data of one's own: render a shipped walk of one
person (CMU subject 7's 07_01), track it with zero-velocity and with the recommended default, the mixture of the
package's pretrained neural prior (:mod:`priors.pretrained`, trained on CMU motion capture without subject 7: a
person it never saw) and zero-velocity, over three tracking seeds each, say in one line what the comparison
shows, and write the error plot and an overlay video of the mixture's first seed -- all through the public API,
as a user's script would. Nothing is trained.

Zero-velocity's step size is the package's default, derived from subject 7's shipped walks (07_01 among them):
the baseline knows this person's pace, the learned prior does not, so the comparison leans toward the baseline.

The output folder is the demo's own, marked by the ``demo.json`` it writes first: a folder holding an earlier
demo's output is replaced whole only when asked (``overwrite``), as every command that writes does, and a
non-empty folder without that mark never is.

What it does and how long it took are log lines (:mod:`logging`, shown by the command line unless ``--quiet``);
the errors of each run, the line saying what they show and the data's attribution are its results, printed to
stdout."""
from __future__ import annotations

import json
import logging
import shutil
from pathlib import Path

import numpy as np

from data_tools.samples import CMU_ATTRIBUTION, sample_walks
from tracker.app.api import TRACK_ANNEALING_LAYERS, load_clip, synthesize, track
from tracker.app.console import progress_bar
from tracker.app.tracking import metrics_line
from tracker.core.errors import InputError

log = logging.getLogger(__name__)


#: What marks a folder as an earlier demo's output (the first thing the demo writes).
DEMO_MARK = "demo.json"
#: The shipped CMU subject whose walk the demo tracks (the pretrained model never saw this person).
TRACK_SUBJECT = 7
#: The tracking seeds of every prior.
SEEDS = (0, 1, 2)
#: The priors compared, by registered name (the mixture given no model file is the pretrained default).
PRIORS = ("zero-velocity", "mixture")
#: How the comparison line names each prior.
PRIOR_LABELS = {"zero-velocity": "zero-velocity",
                "mixture": "the mixture of the pretrained neural prior and zero-velocity"}


def _against(error_mm: float, baseline_mm: float) -> str:
    """How a mean error (mm) compares with a baseline's: ``1.25 times lower``, ``1.10 times higher`` or ``the
    same`` (to the 0.1 mm the errors are printed to)."""
    if round(error_mm, 1) == round(baseline_mm, 1):
        return "the same"
    ratio = max(error_mm, baseline_mm) / min(error_mm, baseline_mm)
    return f"{ratio:.2f} times {'lower' if error_mm < baseline_mm else 'higher'}"


def _spread(errors_mm: list[float]) -> str:
    """``31.2 mm (seeds: 29.0, 31.5, 33.1)``: the mean over the seeds and each seed's mean error (mm)."""
    return f"{np.mean(errors_mm):.1f} mm (seeds: {', '.join(f'{e:.1f}' for e in errors_mm)})"


def comparison_line(errors_mm: dict[str, list[float]], tracked: str) -> str:
    """One line saying what the demo's comparison shows, from each prior's mean marker errors (mm), one per
    tracking seed (``{"zero-velocity": [...], "mixture": [...]}``): which prior tracked best on average, and the
    mixture's mean against zero-velocity's, on ``tracked``, a person the pretrained model never saw."""
    means = {name: float(np.mean(e)) for name, e in errors_mm.items()}
    baseline, mixture = means["zero-velocity"], means["mixture"]
    relation = _against(mixture, baseline)
    if relation == "the same":
        who = "the mixture and zero-velocity tracked alike"
    else:
        who = f"{PRIOR_LABELS[min(means, key=means.get)]} tracked best"
    return (f"What this shows: on {tracked}, a person the pretrained model never saw, {who} over "
            f"{len(errors_mm['mixture'])} seeds: the mixture {_spread(errors_mm['mixture'])}, {relation} "
            f"{'as' if relation == 'the same' else 'than'} zero-velocity's {_spread(errors_mm['zero-velocity'])}; "
            "one short clip: a sketch, not a benchmark.")


def run_demo(out: Path, frames: int = 90, overwrite: bool = False) -> int:
    from data_tools.io.files import check_output_folder, write_text_atomic
    from tracker.app.visualize import error_plot, overlay_frames, write_video

    out = check_output_folder(out, replaceable=(DEMO_MARK,))
    if out.is_dir() and any(out.iterdir()):
        if not overwrite:
            raise InputError("the folder holds an earlier demo's output (pass --overwrite to replace it)", out)
        for entry in out.iterdir():  # the demo's own folder (its mark checked above), replaced whole
            if entry.is_dir() and not entry.is_symlink():
                shutil.rmtree(entry)
            else:
                entry.unlink()
    write_text_atomic(out / DEMO_MARK, json.dumps({"demo": "pose-tracker demo", "frames": frames,
                                                   "seeds": list(SEEDS)}, indent=1))

    asf, walks = sample_walks(TRACK_SUBJECT)
    walk = walks[0]
    log.info(f"1/3 Rendering {frames} frames of CMU walk {walk.stem} (subject {TRACK_SUBJECT}) into 4 cameras "
             "(60 Hz, 640x480)")
    seq = synthesize(load_clip(walk, asf, fps=60.0), out / "sequence", frames=frames, overwrite=True,
                     progress=lambda it: progress_bar(it, desc="rendering", unit="frame"))
    log.info(f"2/3 Tracking with zero-velocity and with the mixture of the pretrained neural prior and "
             f"zero-velocity (no training), 1000 particles, {TRACK_ANNEALING_LAYERS} annealing layers (the "
             f"default), 4 views, seeds {', '.join(map(str, SEEDS))}")
    runs, errors = {}, {name: [] for name in PRIORS}
    for name in PRIORS:
        for seed in SEEDS:
            label = f"{name}, seed {seed}"
            with progress_bar(total=frames - 2, desc=label, unit="frame") as bar:
                runs[label] = track(seq, name, particles=1000, seed=seed,
                                    on_frame=lambda step, e: (bar.update(1),
                                                              bar.set_postfix(mpjpe_abs=f"{e:.0f} mm")))
            folder = out / f"track_{name}_seed{seed}"
            res = runs[label].save(folder, overwrite=True)
            print(f"{label}, {res['frames_tracked']} frames tracked: {metrics_line(res['metrics'])}")
            errors[name].append(res["metrics"]["mpjpe_abs"]["mean"])
            log.info(f"   {runs[label].seconds_per_frame:.3f} s per frame -> {folder}")
    print(comparison_line(errors, f"CMU subject {TRACK_SUBJECT}'s walk {walk.stem}"))
    log.info(f"3/3 Writing the error plot and the overlay video (the mixture's estimates, seed {SEEDS[0]})")
    curves = {label: (np.arange(r.first_tracked, len(r.poses)), r.errors) for label, r in runs.items()}
    error_plot(out / "error_per_frame.png", curves,
               f"Tracking CMU {walk.stem} (pretrained mixture: subject {TRACK_SUBJECT} never seen), 4 views, "
               f"1000 particles, {TRACK_ANNEALING_LAYERS} annealing layers")
    shown = runs[f"mixture, seed {SEEDS[0]}"]
    write_video(out / "overlay.mp4", overlay_frames(seq, shown.poses, list(range(seq.n_views)), shown.errors,
                                                    shown.first_tracked, estimate_name="mixture"), seq.fps)
    log.info(f"   {out / 'error_per_frame.png'}, {out / 'overlay.mp4'}")
    print(CMU_ATTRIBUTION)
    return 0

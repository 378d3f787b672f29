"""Command line: ``python -m tracker <command>`` (the contract: DESIGN.md "Command line", README).

Every bad input ends with a one-line reason on stderr and exit status 2.
"""
from __future__ import annotations

import argparse
import sys
from pathlib import Path
from typing import Sequence

import numpy as np

from likelihoods.edge_silhouette import LikelihoodParams
from tracker.core.errors import InputError

LIKELIHOOD_DEFAULTS = LikelihoodParams()


def _number(kind: type, minimum: float, strict: bool):
    """An argparse type: ``kind`` (int or float), finite, above (``strict``) or at least ``minimum``."""
    noun = "an integer" if kind is int else "a number"
    bound = f"greater than {minimum:g}" if strict else f"at least {minimum:g}"

    def parse(text: str):
        try:
            value = kind(text)
        except ValueError:
            raise argparse.ArgumentTypeError(f"expected {noun}, got {text!r}") from None
        if not np.isfinite(value) or value < minimum or (strict and value == minimum):
            raise argparse.ArgumentTypeError(f"must be {bound}, got {text}")
        return value

    return parse


_positive_float = _number(float, 0.0, strict=True)
_non_negative_float = _number(float, 0.0, strict=False)
_positive_int = _number(int, 1, strict=False)
_non_negative_int = _number(int, 0, strict=False)


class _Parser(argparse.ArgumentParser):
    """argparse with exit status 2 and a one-line message for usage errors."""

    def error(self, message: str) -> None:  # type: ignore[override]
        self.exit(2, f"{self.prog}: error: {message}\n")


def build_parser() -> argparse.ArgumentParser:
    p = _Parser(prog="python -m tracker",
                description="3D human pose tracking with learned dynamical priors.")
    sub = p.add_subparsers(dest="command", metavar="COMMAND", parser_class=_Parser)
    sub.required = True

    c = sub.add_parser("convert", help="convert a mocap clip (AMC+ASF or BVH) to body-model poses and markers",
                       description="Retarget a mocap clip to the 15-cone body model and write CLIP.npz with "
                                   "poses, markers (ground truth), model_markers, fps and the body shape.")
    c.add_argument("--mocap", required=True, help="motion file: .amc (CMU ASF/AMC) or .bvh")
    c.add_argument("--skeleton", help="ASF skeleton for an .amc file (default: <subject>.asf beside it)")
    c.add_argument("--fps", type=_positive_float, default=60.0, help="output frame rate in Hz (default 60)")
    c.add_argument("--length-unit", type=_positive_float, default=None, metavar="MM",
                   help="BVH only: millimetres per file unit (default: inferred from the skeleton's height)")
    c.add_argument("--out", required=True, help="output .npz")

    s = sub.add_parser("synth", help="render a mocap clip into a synthetic multi-view sequence",
                       description="Retarget a mocap clip, render it into a calibrated rig over a cluttered room "
                                   "and write the sequence folder (cameras.json, images/, background/, "
                                   "groundtruth.npz, meta.json).")
    s.add_argument("--mocap", required=True, help="motion file: .amc (CMU ASF/AMC) or .bvh")
    s.add_argument("--skeleton", help="ASF skeleton for an .amc file (default: <subject>.asf beside it)")
    s.add_argument("--out", required=True, help="output sequence folder")
    s.add_argument("--views", type=_positive_int, default=4, help="number of cameras (default 4)")
    s.add_argument("--fps", type=_positive_float, default=60.0, help="frame rate in Hz (default 60)")
    s.add_argument("--start", type=_non_negative_int, default=0, help="first frame, at the output rate (default 0)")
    s.add_argument("--frames", type=_positive_int, default=None, help="number of frames (default: to the end)")
    s.add_argument("--seed", type=int, default=0, help="random seed: scene, clothing, widths, noise (default 0)")
    s.add_argument("--width", type=_positive_int, default=640, help="image width in pixels (default 640)")
    s.add_argument("--height", type=_positive_int, default=480, help="image height in pixels (default 480)")
    s.add_argument("--noise", type=_non_negative_float, default=2.0,
                   help="sensor noise std in grey levels of 255 (default 2)")
    s.add_argument("--lighting-change", type=float, default=0.0, metavar="FRACTION",
                   help="brightness drifts from 1 to 1+FRACTION over the sequence (default 0)")
    s.add_argument("--occluder", action="store_true", help="put a pillar between camera 0 and the person")
    s.add_argument("--missing-camera", type=_non_negative_int, default=None, metavar="INDEX",
                   help="this camera delivers only black frames")
    s.add_argument("--length-unit", type=_positive_float, default=None, metavar="MM",
                   help="BVH only: millimetres per file unit (default: inferred)")

    w = sub.add_parser("show", help="draw the projected body model over every view of a sequence frame",
                       description="Draw the projected cones (ground truth, the initial pose, or --poses) over "
                                   "every camera view in one grid image, or a whole sequence as a video.")
    w.add_argument("sequence", metavar="DIR", help="sequence folder (own layout or PARSEC bodytrack)")
    w.add_argument("--frame", type=_non_negative_int, default=0, help="frame to draw (default 0)")
    w.add_argument("--poses", help="estimates.npz (poses T x D) to draw instead of the ground truth")
    w.add_argument("--out", help="output image (.png)")
    w.add_argument("--video", help="also write every frame to this video (.mp4)")

    r = sub.add_parser("train", help="train a learned motion prior (CRBM) on mocap clips",
                       description="Retarget the clips to the 15-cone model at --fps, convert them to the invariant "
                                   "representation and train a CRBM with contrastive divergence; the model file keeps "
                                   "its normalisation statistics and the data settings it was trained with.")
    r.add_argument("--prior", required=True, choices=["crbm", "gpdm"], help="which prior to train")
    r.add_argument("--mocap", required=True, nargs="+", metavar="FILE", help="training clips (.amc or .bvh)")
    r.add_argument("--skeleton", nargs="+", metavar="ASF",
                   help="ASF skeleton(s): one for all .amc clips or one per clip (default: <subject>.asf beside each)")
    r.add_argument("--fps", type=_positive_float, default=60.0, help="frame rate of the training data (default 60)")
    r.add_argument("--order", type=_positive_int, default=None,
                   help="CRBM order N (default 3) or GPDM dynamics order 1 or 2 (default 1)")
    r.add_argument("--hidden", type=_positive_int, default=150, help="hidden units (default 150)")
    r.add_argument("--epochs", type=_positive_int, default=500, help="passes through the data (default 500)")
    r.add_argument("--cd-k", type=_positive_int, default=10, help="Gibbs steps of contrastive divergence (default 10)")
    r.add_argument("--batch-size", type=_positive_int, default=100, help="windows per mini-batch (default 100)")
    r.add_argument("--history-noise", default="auto",
                   help="std of the noise added to the history in training (normalised units), or 'auto' (default)")
    r.add_argument("--sparsity", type=float, default=None, metavar="TARGET",
                   help="target mean activation of the hidden units (default: no sparsity term)")
    r.add_argument("--seed", type=int, default=0, help="random seed (default 0)")
    r.add_argument("--checkpoint-every", type=_positive_int, default=None, metavar="EPOCHS",
                   help="CRBM: also save the model every this many epochs")
    r.add_argument("--latent-dim", type=_positive_int, default=3, help="GPDM: latent dimensions (default 3)")
    r.add_argument("--dynamics", default="linear+rbf", choices=["linear", "rbf", "linear+rbf"],
                   help="GPDM: dynamics kernel (default linear+rbf)")
    r.add_argument("--balance", type=_positive_float, default=1.0, metavar="M",
                   help="GPDM: exponent M of the prior on the observation hyperparameters (default 1)")
    r.add_argument("--iterations", type=_positive_int, default=300, help="GPDM: L-BFGS iterations (default 300)")
    r.add_argument("--out", required=True, help="output model file (.pt)")

    t = sub.add_parser("track", help="track a person through a sequence with a particle filter",
                       description="Track a sequence (our layout or PARSEC bodytrack) with an SIR particle filter "
                                   "and an edge + silhouette likelihood; writes OUTDIR/result.json and "
                                   "OUTDIR/estimates.npz.")
    t.add_argument("sequence", metavar="DIR", help="sequence folder")
    t.add_argument("--prior", required=True, choices=["zero-velocity", "constant-velocity", "crbm", "gpdm"],
                   help="motion prior")
    t.add_argument("--model", nargs="+", metavar="MODEL",
                   help="trained prior model(s); for crbm several orders (e.g. 1 and 3) grow the history")
    t.add_argument("--gibbs-steps", type=_positive_int, default=30,
                   help="CRBM: alternating Gibbs steps per sample (default 30)")
    t.add_argument("--root-noise", type=_non_negative_float, default=5.0, metavar="MM",
                   help="CRBM, GPDM: ground-plane diffusion of each sample in mm (default 5)")
    t.add_argument("--latent-noise", type=_non_negative_float, default=1.0,
                   help="GPDM: multiple of the predictive standard deviation added to each latent step (default 1)")
    t.add_argument("--particles", type=_positive_int, default=1000, help="number of particles (default 1000)")
    t.add_argument("--views", default=None, help="comma-separated camera indices (default: all)")
    t.add_argument("--frames", type=_positive_int, default=None,
                   help="track frames 0..N-1 (default: the whole sequence)")
    t.add_argument("--seed", type=int, default=0, help="random seed (default 0)")
    t.add_argument("--annealing-layers", type=_positive_int, default=1,
                   help="annealed layers per frame (default 1: plain SIR)")
    t.add_argument("--resampling", default="systematic",
                   choices=["systematic", "stratified", "multinomial", "residual"])
    t.add_argument("--init", help="POSES.npz whose 'poses' are the known first frames (default: ground truth, or "
                                  "the bodytrack InitialPose.txt)")
    t.add_argument("--known-frames", type=_positive_int, default=2,
                   help="known frames the filter starts from (default 2, as in Taylor 2009)")
    t.add_argument("--train-mocap", nargs="+", default=None, metavar="FILE",
                   help="mocap clips whose frame-to-frame changes set the random-walk scale (default: the shipped "
                        "subject-7 walks 07_01 and 07_02); bodytrack folders use PoseParameters.txt")
    t.add_argument("--prior-scale", type=_positive_float, default=1.0,
                   help="multiply the random-walk noise (default 1)")
    t.add_argument("--sharpness", type=_positive_float, default=LIKELIHOOD_DEFAULTS.sharpness,
                   help=f"likelihood sharpness (default {LIKELIHOOD_DEFAULTS.sharpness:g})")
    t.add_argument("--bidirectional", action="store_true",
                   help="also penalise foreground the model does not cover (for monocular tracking)")
    t.add_argument("--out", required=True, help="output folder")
    t.add_argument("--video", help="also write an overlay video of the estimates (.mp4)")

    d = sub.add_parser("demo", help="render, track and score a shipped walk (the built-in default job)",
                       description="Render 1.5 s of the shipped CMU walk 07_02 into 4 cameras, train a CRBM on "
                                   "the other shipped walk, track with the zero-velocity and the CRBM prior (1000 "
                                   "particles), print both errors and write the error-per-frame plot and an "
                                   "overlay video.")
    d.add_argument("--out", default="demo_output", help="output folder (default ./demo_output)")
    d.add_argument("--frames", type=_number(int, 4, strict=False), default=90,
                   help="frames to render and track (default 90: 1.5 s)")
    return p


def _convert_one(mocap: str | Path, skeleton, fps: float, length_unit, out: Path):
    from data_tools.clip_io import save_converted_clip
    from data_tools.load import load_mocap
    from data_tools.retarget import retarget

    clip = load_mocap(mocap, skeleton, length_unit)
    result = retarget(clip, fps=fps)
    out.parent.mkdir(parents=True, exist_ok=True)
    save_converted_clip(result, out)
    return clip, result


def cmd_convert(args: argparse.Namespace) -> int:
    out = Path(args.out)
    if out.suffix != ".npz":
        raise InputError("output must be a .npz file", out)
    clip, result = _convert_one(args.mocap, args.skeleton, args.fps, args.length_unit, out)
    for note in clip.notes:
        print(f"note: {Path(args.mocap).name}: {note}", file=sys.stderr)
    print(f"{Path(args.mocap).name}: {len(result.poses)} frames at {result.fps:g} fps, "
          f"mean retarget residual {result.mean_residual:.2f} mm -> {out}")
    return 0


def cmd_demo(args: argparse.Namespace) -> int:
    from tqdm import tqdm

    from data_tools.load import load_mocap
    from data_tools.retarget import retarget
    from data_tools.samples import CMU_ATTRIBUTION, sample_walks
    from data_tools.sequence import read_sequence
    from data_tools.synth import SynthSettings, synthesize
    from priors.crbm import CRBMConfig, CRBMPrior, train_crbm
    from priors.random_walk import ZeroVelocityPrior, step_rms
    from tracker.app.tracking import track, write_results
    from tracker.engine.filter import FilterSettings
    from tracker.app.visualize import error_plot, overlay_frames, write_video

    out = Path(args.out)
    asf, walks = sample_walks()
    train, test = walks  # 07_01 trains the priors, 07_02 is rendered and tracked
    print(f"1/4 Rendering {args.frames} frames of CMU walk {test.stem} into 4 cameras (60 Hz, 640x480)")
    result = retarget(load_mocap(test, asf), fps=60.0)
    synthesize(result, out / "sequence", SynthSettings(frames=args.frames), source=f"{test.name} (shipped sample)",
               progress=lambda it: tqdm(it, desc="rendering", unit="frame"))
    seq = read_sequence(out / "sequence")
    train_poses = retarget(load_mocap(train, asf), fps=60.0).poses
    print(f"2/4 Training a first-order CRBM (150 hidden units, CD-10, 300 epochs) on {train.stem}")
    crbm = train_crbm([train_poses], CRBMConfig(order=1, hidden=150, epochs=300), 60.0, seq.model.dof_names,
                      seq.model.name, [train.name])
    crbm.save(out / "crbm1.pt")
    print(f"   {crbm.training_seconds:.1f} s, reconstruction error {crbm.reconstruction_errors[0]:.3f} -> "
          f"{crbm.reconstruction_errors[-1]:.3f} -> {out / 'crbm1.pt'}")
    priors = {"zero-velocity": ZeroVelocityPrior(step_rms([train_poses])), "crbm": CRBMPrior([crbm])}
    print("3/4 Tracking with each prior, 1000 particles, 4 views, seed 0")
    runs = {}
    for name, prior in priors.items():
        with tqdm(total=args.frames - 2, desc=name, unit="frame") as bar:
            runs[name] = track(seq, prior, FilterSettings(n_particles=1000), seed=0,
                               on_frame=lambda k, e: (bar.update(1), bar.set_postfix(error_mm=f"{e:.0f}")))
        res = write_results(out / f"track_{name}", runs[name], seq, name, 1000, 0, {})
        print(f"   {name}: mean marker error {res['mean_error_mm']:.1f} ± {res['std_error_mm']:.1f} mm over "
              f"{res['frames']} frames, {runs[name].seconds_per_frame:.3f} s per frame -> {out / f'track_{name}'}")
    print("4/4 Writing the error plot and the overlay video (CRBM estimates)")
    curves = {name: (np.arange(r.first_tracked, len(r.poses)), r.errors) for name, r in runs.items()}
    error_plot(out / "error_per_frame.png", curves, f"Tracking CMU {test.stem}, 4 views, 1000 particles")
    best = runs["crbm"]
    write_video(out / "overlay.mp4", overlay_frames(seq, best.poses, best.views, best.errors, best.first_tracked),
                seq.fps)
    print(f"   {out / 'error_per_frame.png'}, {out / 'overlay.mp4'}")
    print(CMU_ATTRIBUTION)
    return 0


def cmd_synth(args: argparse.Namespace) -> int:
    from tqdm import tqdm

    from data_tools.load import load_mocap
    from data_tools.retarget import retarget
    from data_tools.synth import SynthSettings, synthesize

    settings = SynthSettings(views=args.views, fps=args.fps, start=args.start, frames=args.frames, seed=args.seed,
                             width=args.width, height=args.height, noise=args.noise,
                             lighting_change=args.lighting_change, occluder=args.occluder,
                             missing_camera=args.missing_camera)
    clip = load_mocap(args.mocap, args.skeleton, args.length_unit)
    for note in clip.notes:
        print(f"note: {Path(args.mocap).name}: {note}", file=sys.stderr)
    result = retarget(clip, fps=args.fps)
    out = synthesize(result, args.out, settings, source=str(args.mocap),
                     progress=lambda it: tqdm(it, desc="rendering", unit="frame"))
    print(f"{Path(args.mocap).name}: {out.n_frames} frames x {args.views} views at "
          f"{result.fps:g} fps -> {out.root} ({out.render_seconds / out.n_frames * 1000:.0f} ms per frame "
          f"to render and write)")
    return 0


def cmd_show(args: argparse.Namespace) -> int:
    import cv2
    from tqdm import tqdm

    from data_tools.sequence import read_sequence
    from tracker.app.tracking import read_poses_file
    from tracker.app.visualize import overlay_grid, write_video

    if not args.out and not args.video:
        raise InputError("nothing to write: give --out FILE.png and/or --video FILE.mp4")
    if args.out and Path(args.out).suffix.lower() != ".png":
        raise InputError("--out must be a .png file", args.out)
    if args.video and Path(args.video).suffix.lower() != ".mp4":
        raise InputError("--video must be an .mp4 file", args.video)
    seq = read_sequence(args.sequence)
    if args.poses:
        poses = read_poses_file(args.poses, "poses", seq.model)
    elif seq.groundtruth is not None:
        poses = seq.groundtruth.poses
    elif seq.initial_poses is not None:
        poses = seq.initial_poses
    else:
        raise InputError("the sequence has no ground truth or initial pose; give --poses", seq.root)
    views = list(range(seq.n_views))
    seq.check_frame(args.frame)
    if args.frame >= len(poses):
        raise InputError(f"no pose for frame {args.frame}: {len(poses)} pose(s) available", args.poses or seq.root)
    if args.out:
        out = Path(args.out)
        out.parent.mkdir(parents=True, exist_ok=True)
        if not cv2.imwrite(str(out), cv2.cvtColor(overlay_grid(seq, poses[args.frame], args.frame, views, f"frame {args.frame}"),
                                               cv2.COLOR_RGB2BGR)):
            raise InputError("cannot write image", out)
        print(f"frame {args.frame}, {seq.n_views} views -> {out}")
    if args.video:
        n = min(seq.n_frames, len(poses))
        frames = (overlay_grid(seq, poses[k], k, views, f"frame {k}") for k in tqdm(range(n), desc="video",
                                                                                    unit="frame"))
        write_video(Path(args.video), frames, seq.fps or 25.0)
        print(f"{n} frames -> {args.video}")
    return 0


def _parse_views(text: str | None, n_views: int) -> list[int]:
    if text is None:
        return list(range(n_views))
    try:
        views = [int(v) for v in text.split(",") if v.strip() != ""]
    except ValueError:
        raise InputError(f"--views must be comma-separated camera indices, got {text!r}") from None
    if not views or len(set(views)) != len(views):
        raise InputError(f"--views must list distinct camera indices, got {text!r}")
    bad = [v for v in views if not 0 <= v < n_views]
    if bad:
        raise InputError(f"--views {bad} out of range: the sequence has {n_views} cameras (0..{n_views - 1})")
    return views


def _training_poses(files: list[str] | None, fps: float) -> list[np.ndarray]:
    """Retargeted poses of the training clips (default: the shipped walks) at the tracking rate."""
    from data_tools.load import load_mocap
    from data_tools.retarget import retarget
    from data_tools.samples import sample_walks

    if files is None:
        asf, walks = sample_walks()
        clips = [load_mocap(w, asf) for w in walks]
    else:
        clips = [load_mocap(f) for f in files]
    return [retarget(c, fps=fps).poses for c in clips]


def build_random_walk_prior(name: str, seq, train_files: list[str] | None, scale: float):
    """The zero- or constant-velocity prior for ``seq``, its noise from training clips (15-cone sequences) or
    from ``PoseParameters.txt`` (bodytrack)."""
    from priors.random_walk import ConstantVelocityPrior, ZeroVelocityPrior, step_rms

    if seq.layout == "bodytrack":
        if seq.diffusion_std is None:
            raise InputError("bodytrack folder has no PoseParameters.txt for the random-walk scale", seq.root)
        std = seq.diffusion_std
    else:
        if seq.fps is None:
            raise InputError("the sequence states no frame rate (groundtruth.npz or meta.json 'fps')", seq.root)
        std = step_rms(_training_poses(train_files, seq.fps))
        if len(std) != seq.model.n_dofs:
            raise InputError(f"training clips have {len(std)} pose numbers, the sequence's model "
                             f"{seq.model.n_dofs}")
    std = std * scale
    return ZeroVelocityPrior(std) if name == "zero-velocity" else ConstantVelocityPrior(std)


def _training_clips(files: list[str], skeletons: list[str] | None, fps: float):
    from data_tools.load import load_mocap
    from data_tools.retarget import retarget

    if skeletons and len(skeletons) not in (1, len(files)):
        raise InputError(f"give one --skeleton for all clips or one per clip ({len(files)}), got {len(skeletons)}")
    results = []
    for i, f in enumerate(files):
        skel = None if not skeletons else skeletons[0 if len(skeletons) == 1 else i]
        if skel is not None and not str(f).lower().endswith(".amc"):
            skel = None
        results.append(retarget(load_mocap(f, skel), fps=fps))
    return results


def cmd_train(args: argparse.Namespace) -> int:
    from tqdm import tqdm

    out = Path(args.out)
    results = _training_clips(args.mocap, args.skeleton, args.fps)
    model0 = results[0].model
    frames = sum(len(r.poses) for r in results)
    clips = [r.poses for r in results]
    sources = [str(f) for f in args.mocap]
    if args.prior == "gpdm":
        from priors.gpdm import GPDMConfig, train_gpdm_prior

        config = GPDMConfig(latent_dim=args.latent_dim, dynamics=args.dynamics, order=args.order or 1,
                            balance=args.balance, iterations=args.iterations, seed=args.seed).check()
        print(f"training a {config.latent_dim}D GPDM ({config.dynamics} dynamics, order {config.order}, "
              f"M = {config.balance:g}) on {len(results)} clip(s), {frames} frames at {args.fps:g} fps")
        with tqdm(total=config.iterations, desc="L-BFGS", unit="it") as bar:
            def progress(done: int, value: float) -> None:
                bar.update(done - bar.n)
                bar.set_postfix(objective=f"{value:.1f}")

            model = train_gpdm_prior(clips, config, args.fps, model0.dof_names, model0.name, sources, progress)
        model.save(out)
        h = model.gpdm.objective_history
        print(f"objective {h[0]:.1f} -> {h[-1]:.1f}, {model.gpdm.training_seconds:.1f} s -> {out}")
        return 0
    from priors.crbm import CRBMConfig, train_crbm

    noise = args.history_noise
    if noise != "auto":
        try:
            noise = float(noise)
        except ValueError:
            raise InputError(f"--history-noise must be 'auto' or a number, got {noise!r}") from None
    config = CRBMConfig(order=args.order or 3, hidden=args.hidden, epochs=args.epochs, cd_k=args.cd_k,
                        batch_size=args.batch_size, history_noise=noise, sparsity_target=args.sparsity,
                        seed=args.seed).check()
    print(f"training a CRBM of order {config.order} with {args.hidden} hidden units on {len(results)} clip(s), "
          f"{frames} frames at {args.fps:g} fps")
    with tqdm(total=args.epochs, desc="CD-%d" % args.cd_k, unit="epoch") as bar:
        def progress(epoch: int, err: float) -> None:
            bar.update(1)
            bar.set_postfix(reconstruction=f"{err:.4f}")

        model = train_crbm(clips, config, args.fps, model0.dof_names, model0.name, sources, progress,
                           (out, args.checkpoint_every) if args.checkpoint_every else None)
    model.save(out)
    errs = model.reconstruction_errors
    print(f"reconstruction error {errs[0]:.4f} (epoch 1) -> {errs[-1]:.4f} (epoch {len(errs)}), "
          f"{model.training_seconds:.1f} s -> {out}")
    return 0


def build_prior(args: argparse.Namespace, seq):
    """The prior named on the command line, checked against the sequence."""
    if args.prior in ("zero-velocity", "constant-velocity"):
        if args.model:
            raise InputError(f"--model is for learned priors; {args.prior} takes its scale from --train-mocap")
        return build_random_walk_prior(args.prior, seq, args.train_mocap, args.prior_scale)
    if not args.model:
        raise InputError(f"--prior {args.prior} needs --model MODEL (train one with python -m tracker train "
                         f"--prior {args.prior})")
    if args.prior == "gpdm":
        from priors.gpdm import GPDMPrior, load_gpdm_prior

        if len(args.model) != 1:
            raise InputError("--prior gpdm takes one --model")
        model = load_gpdm_prior(args.model[0])
        model.check_compatible(seq.model.name, seq.model.dof_names, seq.fps, args.model[0])
        return GPDMPrior(model, noise_scale=args.latent_noise, root_noise_mm=args.root_noise, seed=args.seed)
    from priors.crbm import CRBMPrior, load_crbm

    models = [load_crbm(m) for m in args.model]
    for path, m in zip(args.model, models):
        m.check_compatible(seq.model.name, seq.model.dof_names, seq.fps, path)
    return CRBMPrior(models, gibbs_steps=args.gibbs_steps, seed=args.seed, root_noise_mm=args.root_noise)


def cmd_track(args: argparse.Namespace) -> int:
    from tqdm import tqdm

    from data_tools.sequence import read_sequence
    from tracker.app.tracking import read_poses_file, track, write_results
    from tracker.engine.filter import FilterSettings
    from tracker.app.visualize import overlay_frames, write_video

    if args.video and Path(args.video).suffix.lower() != ".mp4":
        raise InputError("--video must be an .mp4 file", args.video)
    seq = read_sequence(args.sequence)
    views = _parse_views(args.views, seq.n_views)
    if args.frames is not None and args.frames > seq.n_frames:
        raise InputError(f"--frames {args.frames} is past the end of the sequence ({seq.n_frames} frames)", seq.root)
    prior = build_prior(args, seq)
    init = read_poses_file(args.init, "initial poses") if args.init else None
    settings = FilterSettings(n_particles=args.particles, resampling=args.resampling,
                              annealing_layers=args.annealing_layers)
    lparams = LikelihoodParams(sharpness=args.sharpness, bidirectional=args.bidirectional)
    T = args.frames or seq.n_frames
    errors: list[float] = []
    with tqdm(total=T, desc=f"tracking ({args.prior})", unit="frame") as bar:
        def on_frame(k: int, err: float | None) -> None:
            bar.update(1)
            if err is not None:
                errors.append(err)
                bar.set_postfix(error_mm=f"{err:.0f}", mean_mm=f"{np.mean(errors):.0f}")

        run = track(seq, prior, settings, args.seed, views, args.frames, args.known_frames, init, lparams,
                    on_frame=on_frame)
        bar.update(T - bar.n)
    out = Path(args.out)
    result = write_results(out, run, seq, args.prior, args.particles, args.seed,
                           {"annealing_layers": args.annealing_layers, "resampling": args.resampling,
                            "sharpness": args.sharpness, "bidirectional": args.bidirectional})
    if run.filter.recovered:
        print(f"warning: no particle explained frame(s) {result['recovered_frames']}; the filter re-diffused "
              f"around its last estimate", file=sys.stderr)
    err = "" if run.mean_error is None else (f", mean error {result['mean_error_mm']:.1f} "
                                             f"± {result['std_error_mm']:.1f} mm")
    print(f"{result['frames']} frames tracked with {args.particles} particles, {len(views)} view(s), "
          f"{args.prior}{err}, {run.seconds_per_frame:.3f} s per frame -> {out}")
    if args.video:
        write_video(Path(args.video), overlay_frames(seq, run.poses, views, run.errors, run.first_tracked),
                    seq.fps or 25.0)
        print(f"overlay video -> {args.video}")
    return 0


COMMANDS = {"convert": cmd_convert, "synth": cmd_synth, "show": cmd_show, "train": cmd_train, "track": cmd_track,
            "demo": cmd_demo}


def main(argv: Sequence[str] | None = None) -> int:
    args = build_parser().parse_args(argv)
    try:
        return COMMANDS[args.command](args)
    except InputError as exc:
        print(f"error: {exc}", file=sys.stderr)
        return 2

"""Bad-input corpus, by class: generate malformed inputs, run the command line on each, classify.

Run by hand (sequentially, one core; a few minutes on the 2-core machine)::

    python benchmarks/bad_input_corpus.py [--only CLASS[,CLASS]] [--timeout 60] [--keep DIR] [--verbose]

For every class of malformed input listed here (ASF hierarchies that are
not trees, text that is not UTF-8, byte-order marks, deep JSON, broken ``.npz``
files, wrong-type ``meta.json`` fields, broken CRBM and GPDM model files, absurd
finite values, huge-noise options, images whose header claims too many pixels,
bad seeds, AMC roots at 1e300, complex or 1e308 ground truth, a camera without
calibration, another subject's skeleton, output-path problems for every command,
``synth`` over an existing folder, greyscale images, tabs in BVH, one-frame
clips), it builds the input from tiny valid files (the shipped sample walks, a
4-frame 2-view 160x120 render, a CRBM and a GPDM trained for seconds), runs
``python -m tracker ...`` on it in a subprocess with a timeout and classifies the
outcome:

* ``clean refusal``: exit 2, exactly one stderr line that names a file or argument, no traceback;
* ``success``: exit 0 and every output finite (and, for ``synth --overwrite``, a consistent folder);
* ``traceback``: a Python traceback, or an exit status other than 0, 2 or 130;
* ``hang``: still running at the timeout;
* ``buried refusal``: exit 2 but more than one stderr line (warnings, progress bars, library messages);
* ``unnamed refusal``: exit 2 and one line that names neither the file nor the argument;
* ``garbage accepted``: exit 0 where the input is invalid, or non-finite output;
* ``harmless refused``: exit 2 for an input that should work (a byte-order mark, a one-frame clip, ...);
* ``partial output``: a refusal that left an output file or folder behind.

It prints a table of counts per class and lists every failure (anything but a
clean refusal of bad input and a success on good input). The small valid files
come from the builders of ``tests/faults/test_bad_input_readers.py``.
"""
from __future__ import annotations

import argparse
import json
import math
import os
import shutil
import subprocess
import sys
import tempfile
import time
from dataclasses import dataclass, field
from pathlib import Path
from typing import Callable

import numpy as np

REPO = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(REPO))

SHARED_MOCAP = Path(os.environ.get("TRACKER_SHARED", REPO.parent / "shared")) / "mocap" / "cmu"
UNWRITABLE = Path("/proc/bad-input-corpus")  # no one, not even root, can create anything here

OK_OUTCOMES = {"refuse": "clean refusal", "accept": "success"}


@dataclass
class Case:
    """One malformed (or harmless) input and the command that reads it."""

    cls: str
    name: str
    args: list[str]
    expect: str  # "refuse" (bad input) or "accept" (harmless input that must work)
    names: tuple[str, ...] = ()  # the refusal line must contain one of these (a file name or a flag)
    outputs: tuple[Path, ...] = ()  # on success: files or folders whose numbers must all be finite
    absent: tuple[Path, ...] = ()  # after a refusal: paths that must not exist (nothing half-written)
    check: Callable[[], str | None] | None = None  # on success: a further check, returning a problem or None


@dataclass
class Outcome:
    case: Case
    kind: str
    seconds: float
    detail: str = ""


@dataclass
class Fixtures:
    """The valid inputs every case starts from (built once)."""

    root: Path
    asf: Path
    amc: Path
    seq: Path
    bodytrack: Path
    crbm: Path
    gpdm: Path
    bvh: Path | None
    a_file: Path
    counter: list[int] = field(default_factory=lambda: [0])

    def case_dir(self) -> Path:
        """A fresh folder for one case."""
        self.counter[0] += 1
        d = self.root / "cases" / f"{self.counter[0]:04d}"
        d.mkdir(parents=True)
        return d


# ---------------------------------------------------------------------------
# Valid inputs
# ---------------------------------------------------------------------------

def build_fixtures(root: Path) -> Fixtures:
    import torch

    import tracker
    from data_tools.samples import sample_walks
    from tests.faults.test_bad_input_readers import tiny_bodytrack

    asf, walks = sample_walks()
    clip = tracker.load_clip(walks[1], asf, fps=60.0)
    seq = root / "seq"
    tracker.synthesize(clip, seq, frames=4, views=2, width=160, height=120, seed=0)
    bodytrack = tiny_bodytrack(root / "bodytrack")
    torch.set_num_threads(1)
    crbm = root / "crbm1.pt"
    tracker.train("crbm", [walks[0]], skeletons=[asf], order=1, epochs=2, hidden=8, grow_from="none",
                  rng=0).save(crbm)
    gpdm = root / "gpdm.pt"
    tracker.train("gpdm", [walks[0]], skeletons=[asf], iterations=10).save(gpdm)
    a_file = root / "a_file"
    a_file.write_text("a file, not a folder\n")
    return Fixtures(root, asf, walks[0], seq, bodytrack, crbm, gpdm, small_bvh(root / "10_03.bvh", 12), a_file)


def small_bvh(path: Path, frames: int) -> Path | None:
    """The first ``frames`` frames of the shared CMU BVH 10_03 (None without ../shared)."""
    source = SHARED_MOCAP / "bvh" / "10_03.bvh"
    if not source.exists():
        return None
    lines = source.read_text().splitlines()
    start = lines.index("MOTION")
    lines[start + 1] = f"Frames:\t{frames}"
    path.write_text("\n".join(lines[:start + 3 + frames]) + "\n")
    return path


def copy_sequence(fx: Fixtures, d: Path) -> Path:
    return Path(shutil.copytree(fx.seq, d / "seq"))


def copy_bodytrack(fx: Fixtures, d: Path) -> Path:
    return Path(shutil.copytree(fx.bodytrack, d / "bt"))


def track_args(seq: Path, out: Path, *extra: str, prior: str = "zero-velocity") -> list[str]:
    return ["track", str(seq), "--prior", prior, "--particles", "20", "--frames", "4", "--checkpoint-every", "0",
            "--out", str(out), *extra]


def track_case(cls: str, name: str, seq: Path, d: Path, expect: str, names: tuple[str, ...], *extra: str,
               prior: str = "zero-velocity") -> Case:
    out = d / "out"
    return Case(cls, name, track_args(seq, out, *extra, prior=prior), expect, names,
                outputs=(out / "estimates.npz", out / "result.json"), absent=(out / "estimates.npz",))


def show_case(cls: str, name: str, seq: Path, d: Path, expect: str, names: tuple[str, ...], *extra: str) -> Case:
    out = d / "frame.png"
    return Case(cls, name, ["show", str(seq), "--out", str(out), *extra], expect, names, outputs=(out,),
                absent=(out,))


def convert_case(cls: str, name: str, mocap: Path, d: Path, expect: str, names: tuple[str, ...], *extra: str
                 ) -> Case:
    out = d / "clip.npz"
    return Case(cls, name, ["convert", "--mocap", str(mocap), "--out", str(out), *extra], expect, names,
                outputs=(out,), absent=(out,))


def train_args(fx: Fixtures, out: Path, *extra: str, prior: str = "crbm") -> list[str]:
    fast = ["--order", "1", "--epochs", "1", "--hidden", "4", "--grow-from", "none"] if prior == "crbm" \
        else ["--iterations", "10"]
    return ["train", "--prior", prior, "--mocap", str(fx.amc), "--skeleton", str(fx.asf), *fast, "--out", str(out),
            *extra]


# ---------------------------------------------------------------------------
# The cases, by class
# ---------------------------------------------------------------------------

def asf_hierarchy(fx: Fixtures) -> list[Case]:
    from tests.faults.test_bad_input_readers import _hierarchy_case, write_lines

    cases = []
    for label in ("cycle", "root as child", "two parents", "self loop"):
        d = fx.case_dir()
        lines, _ = _hierarchy_case(label)
        asf = write_lines(d / "07.asf", lines)
        cases.append(convert_case("ASF hierarchy", label, fx.amc, d, "refuse", ("07.asf",), "--skeleton", str(asf)))
    return cases


def _text_targets(fx: Fixtures, d: Path) -> dict[str, tuple[Path, Callable[[str, tuple[str, ...]], Case]]]:
    """Each text family: the file to damage in a fresh copy, and the case that reads it."""
    seq, bt = copy_sequence(fx, d), copy_bodytrack(fx, d)
    asf, amc, bvh = d / "07.asf", d / "07_01.amc", d / "small.bvh"
    shutil.copy(fx.asf, asf)
    shutil.copy(fx.amc, amc)
    targets = {
        "cameras.json": (seq / "cameras.json", lambda e, n: show_case("", "", seq, d, e, n)),
        "meta.json": (seq / "meta.json", lambda e, n: show_case("", "", seq, d, e, n)),
        ".cal": (bt / "CALIB" / "Camera1.cal", lambda e, n: show_case("", "", bt, d, e, n)),
        "BodyShapeParameters.txt": (bt / "BodyShapeParameters.txt", lambda e, n: show_case("", "", bt, d, e, n)),
        "InitialPose.txt": (bt / "InitialPose.txt", lambda e, n: show_case("", "", bt, d, e, n)),
        "ASF": (asf, lambda e, n: convert_case("", "", amc, d, e, n, "--skeleton", str(asf))),
        "AMC": (amc, lambda e, n: convert_case("", "", amc, d, e, n, "--skeleton", str(asf))),
    }
    if fx.bvh is not None:
        shutil.copy(fx.bvh, bvh)
        targets["BVH"] = (bvh, lambda e, n: convert_case("", "", bvh, d, e, n))
    return targets


def _named(case: Case, cls: str, name: str) -> Case:
    case.cls, case.name = cls, name
    return case


TEXT_FAMILIES = ("cameras.json", "meta.json", ".cal", "BodyShapeParameters.txt", "InitialPose.txt", "ASF", "AMC",
                 "BVH")


def not_utf8(fx: Fixtures) -> list[Case]:
    cases = []
    for family in TEXT_FAMILIES:
        for encoding in ("latin-1", "utf-16", "binary"):
            d = fx.case_dir()
            if family not in (targets := _text_targets(fx, d)):
                continue
            path, make = targets[family]
            text = path.read_text(encoding="utf-8")
            if encoding == "latin-1":
                first, rest = text.split("\n", 1)
                data = (first + " \xe9\n" + rest).encode("latin-1")
            elif encoding == "utf-16":
                data = text.encode("utf-16")
            else:
                data = bytes(np.random.default_rng(len(cases)).integers(0, 256, 400, dtype=np.uint8))
            path.write_bytes(data)
            cases.append(_named(make("refuse", (path.name,)), "text not UTF-8", f"{family} {encoding}"))
    return cases


def byte_order_marks(fx: Fixtures) -> list[Case]:
    cases = []
    for family in TEXT_FAMILIES:
        d = fx.case_dir()
        if family not in (targets := _text_targets(fx, d)):
            continue
        path, make = targets[family]
        path.write_bytes(b"\xef\xbb\xbf" + path.read_bytes())
        cases.append(_named(make("accept", ()), "byte-order mark (harmless)", family))
    return cases


def deep_json(fx: Fixtures) -> list[Case]:
    cases = []
    for name in ("cameras.json", "meta.json"):
        d = fx.case_dir()
        seq = copy_sequence(fx, d)
        (seq / name).write_text("[" * 100000 + "]" * 100000)
        cases.append(show_case("deep JSON", name, seq, d, "refuse", (name,)))
    d = fx.case_dir()
    seq = copy_sequence(fx, d)
    text = (seq / "meta.json").read_text().rstrip()
    (seq / "meta.json").write_text(text[:-1] + ', "deep": ' + '{"a": ' * 3000 + "null" + "}" * 3000 + "}")
    cases.append(show_case("deep JSON", "meta.json 3000 objects deep", seq, d, "refuse", ("meta.json",)))
    return cases


def _npz_bytes(arrays: dict) -> bytes:
    import io

    buf = io.BytesIO()
    np.savez(buf, **arrays)
    return buf.getvalue()


def _groundtruth(seq: Path) -> dict[str, np.ndarray]:
    with np.load(seq / "groundtruth.npz") as z:
        return {k: z[k] for k in z.files}


def npz_files(fx: Fixtures) -> list[Case]:
    cases = []
    gt = _groundtruth(fx.seq)
    variants = {
        "empty": b"",
        "truncated": _npz_bytes(gt)[:300],
        "not a zip": b"poses 1 2 3\n",
        "a single .npy": None,
        "fps 1-d": {**gt, "fps": np.array([60.0, 30.0])},
        "fps string": {**gt, "fps": np.array("sixty")},
        "fps 0-d zero": {**gt, "fps": np.float64(0.0)},
        "poses strings": {**gt, "poses": np.full(gt["poses"].shape, "a")},
        "poses object": {**gt, "poses": np.array([None] * 4, dtype=object)},
        "zero rows": {**gt, "poses": gt["poses"][:0], "markers": gt["markers"][:0]},
    }
    for label, spec in variants.items():
        d = fx.case_dir()
        seq = copy_sequence(fx, d)
        target = seq / "groundtruth.npz"
        if spec is None:
            np.save(d / "x.npy", gt["poses"])
            shutil.move(d / "x.npy", target)
        elif isinstance(spec, bytes):
            target.write_bytes(spec)
        else:
            target.write_bytes(_npz_bytes(spec))  # object arrays are pickled inside
        cases.append(track_case(".npz file", f"groundtruth {label}", seq, d, "refuse", ("groundtruth.npz",)))
    init_variants = {
        "zero rows": {"poses": np.zeros((0, 40))},
        "string poses": {"poses": np.full((2, 40), "x")},
        "one column": {"poses": np.zeros((2, 1))},
        "NaN": {"poses": np.full((2, 40), np.nan)},
        "empty file": b"",
    }
    for label, spec in init_variants.items():
        d = fx.case_dir()
        init = d / "init.npz"
        init.write_bytes(spec if isinstance(spec, bytes) else _npz_bytes(spec))
        cases.append(track_case(".npz file", f"--init {label}", fx.seq, d, "refuse", ("init.npz",),
                                "--init", str(init)))
    for label, spec in {"truncated": _npz_bytes(gt)[:200], "string poses": {"poses": np.full((4, 40), "x")}}.items():
        d = fx.case_dir()
        poses = d / "estimates.npz"
        poses.write_bytes(spec if isinstance(spec, bytes) else _npz_bytes(spec))
        cases.append(show_case(".npz file", f"show --poses {label}", fx.seq, d, "refuse", ("estimates.npz",),
                               "--poses", str(poses)))
    return cases


def meta_fields(fx: Fixtures) -> list[Case]:
    edits = {
        "length a string": lambda m: m["body_shape"]["lengths"].update(torso="480"),
        "lengths a list": lambda m: m["body_shape"].update(lengths=[480]),
        "offset a string": lambda m: m["body_shape"].update(left_hip_offset="0 90 -80"),
        "body_shape a list": lambda m: m.update(body_shape=[1, 2]),
        "fps a string": lambda m: m.update(fps="60"),
        "fps a list": lambda m: m.update(fps=[60]),
        "fps negative": lambda m: m.update(fps=-60),
        "top level a list": None,
    }
    cases = []
    for label, edit in edits.items():
        d = fx.case_dir()
        seq = copy_sequence(fx, d)
        meta = json.loads((seq / "meta.json").read_text())
        if edit is None:
            meta = [meta]
        else:
            edit(meta)
        (seq / "meta.json").write_text(json.dumps(meta))
        cases.append(track_case("meta.json fields", label, seq, d, "refuse", ("meta.json",)))
    return cases


def _model_cases(fx: Fixtures, cls: str, model: Path, prior: str, edits: dict[str, Callable[[dict], None]]
                 ) -> list[Case]:
    import torch

    cases = []
    for label, edit in edits.items():
        d = fx.case_dir()
        bad = d / "model.pt"
        if label == "foreign file":
            bad.write_text("not a model\n")
        elif label == "truncated file":
            bad.write_bytes(model.read_bytes()[:2000])
        elif label == "other prior's file":
            shutil.copy(fx.gpdm if prior == "crbm" else fx.crbm, bad)
        else:
            doc = torch.load(model, weights_only=True)
            edit(doc)
            torch.save(doc, bad)
        cases.append(track_case(cls, label, fx.seq, d, "refuse", ("model.pt",), "--model", str(bad), prior=prior))
    return cases


def crbm_models(fx: Fixtures) -> list[Case]:
    import torch

    nan = float("nan")
    edits = {
        "missing key": lambda d: d.pop("pose_step_rms"),
        "missing weight": lambda d: d["params"].pop("W"),
        "wrong-shaped weight": lambda d: d["params"].__setitem__("A", d["params"]["A"][:5]),
        "unknown config key": lambda d: d["config"].__setitem__("learning_rat", 1.0),
        "string fps": lambda d: d.__setitem__("fps", "sixty"),
        "fps 1e308": lambda d: d.__setitem__("fps", 1e308),
        "NaN weights": lambda d: d["params"].__setitem__("W", d["params"]["W"] * nan),
        "zero normaliser std": lambda d: d["normaliser"].__setitem__("std", d["normaliser"]["std"] * 0),
        "infinite normaliser std": lambda d: d["normaliser"].__setitem__("std", d["normaliser"]["std"] * math.inf),
        "normaliser mean NaN": lambda d: d["normaliser"].__setitem__("mean", d["normaliser"]["mean"] * nan),
        "string order": lambda d: d["config"].__setitem__("order", "one"),
        "dof_names not a list": lambda d: d.__setitem__("dof_names", 5),
        "pose_step_rms NaN": lambda d: d.__setitem__("pose_step_rms", torch.full_like(d["pose_step_rms"], nan)),
        "foreign file": None, "truncated file": None, "other prior's file": None,
    }
    return _model_cases(fx, "CRBM model file", fx.crbm, "crbm", edits)


def gpdm_models(fx: Fixtures) -> list[Case]:
    import torch

    nan = float("nan")
    extra = lambda key, value: lambda d: d["extra"].__setitem__(key, value)  # noqa: E731
    edits = {
        "missing key X": lambda d: d.pop("X"),
        "missing key log_beta": lambda d: d.pop("log_beta"),
        "missing normaliser": lambda d: d["extra"].pop("normaliser"),
        "wrong-shaped X": lambda d: d.__setitem__("X", d["X"][:, :2]),
        "wrong-shaped Y": lambda d: d.__setitem__("Y", d["Y"][:-3]),
        "wrong-shaped W": lambda d: d.__setitem__("W", d["W"][:3]),
        "wrong-shaped log_alpha": lambda d: d.__setitem__("log_alpha", d["log_alpha"][:1]),
        "X a list": lambda d: d.__setitem__("X", d["X"].tolist()),
        "NaN X": lambda d: d.__setitem__("X", d["X"] * nan),
        "NaN log_beta": lambda d: d.__setitem__("log_beta", d["log_beta"] * nan),
        "kernel scale 0 (log -inf)": lambda d: d["log_alpha"].__setitem__(0, -math.inf),
        "noise precision inf": lambda d: d["log_beta"].__setitem__(2, math.inf),
        "W zero": lambda d: d.__setitem__("W", d["W"] * 0),
        "W negative": lambda d: d.__setitem__("W", -d["W"]),
        "unknown config key": lambda d: d["config"].__setitem__("latent_dims", 3),
        "config latent_dim string": lambda d: d["config"].__setitem__("latent_dim", "3"),
        "lengths do not add up": lambda d: d.__setitem__("lengths", [5]),
        "active out of range": lambda d: d.__setitem__("active", torch.tensor([0, 10 ** 6])),
        "string fps": extra("fps", "sixty"),
        "fps 1e308": extra("fps", 1e308),
        "fps zero": extra("fps", 0.0),
        "zero normaliser std": lambda d: d["extra"]["normaliser"].__setitem__(
            "std", d["extra"]["normaliser"]["std"] * 0),
        "infinite normaliser std": lambda d: d["extra"]["normaliser"].__setitem__(
            "std", d["extra"]["normaliser"]["std"] * math.inf),
        "pose_step_rms NaN": lambda d: d["extra"].__setitem__(
            "pose_step_rms", d["extra"]["pose_step_rms"] * nan),
        "extra not a dict": lambda d: d.__setitem__("extra", [1]),
        "foreign file": None, "truncated file": None, "other prior's file": None,
    }
    return _model_cases(fx, "GPDM model file", fx.gpdm, "gpdm", edits)


def absurd_values(fx: Fixtures) -> list[Case]:
    cases = []
    d = fx.case_dir()
    seq = copy_sequence(fx, d)
    rig = json.loads((seq / "cameras.json").read_text())
    rig["cameras"][0]["fx"] = 1e308
    (seq / "cameras.json").write_text(json.dumps(rig))
    cases.append(track_case("absurd finite values", "cameras.json focal 1e308", seq, d, "refuse", ("cameras.json",)))
    d = fx.case_dir()
    seq = copy_sequence(fx, d)
    meta = json.loads((seq / "meta.json").read_text())
    meta["body_shape"]["lengths"]["torso"] = 1e308
    (seq / "meta.json").write_text(json.dumps(meta))
    cases.append(track_case("absurd finite values", "meta.json body size 1e308", seq, d, "refuse", ("meta.json",)))
    d = fx.case_dir()
    bt = copy_bodytrack(fx, d)
    numbers = (bt / "CALIB" / "Camera1.cal").read_text().split()
    numbers[0] = "1e308"
    (bt / "CALIB" / "Camera1.cal").write_text("\n".join(numbers) + "\n")
    cases.append(show_case("absurd finite values", ".cal focal 1e308", bt, d, "refuse", ("Camera1.cal",)))
    d = fx.case_dir()
    bt = copy_bodytrack(fx, d)
    (bt / "BodyShapeParameters.txt").write_text("1e308\n" * 58)
    cases.append(show_case("absurd finite values", "bodytrack body size 1e308", bt, d, "refuse",
                           ("BodyShapeParameters.txt",)))
    d = fx.case_dir()
    bt = copy_bodytrack(fx, d)
    (bt / "InitialPose.txt").write_text(" ".join(["1e308"] * 31) + "\n")
    cases.append(show_case("absurd finite values", "bodytrack initial pose 1e308", bt, d, "refuse",
                           ("InitialPose.txt",)))
    for flag, value in (("--fps", "1e308"), ("--fps", "1e-300"), ("--length-unit", "1e308")):
        d = fx.case_dir()
        mocap = fx.amc if flag == "--fps" else _tiny_bvh(d)
        cases.append(convert_case("absurd finite values", f"convert {flag} {value}", mocap, d, "refuse", (flag,),
                                  flag, value, *(("--skeleton", str(fx.asf)) if flag == "--fps" else ())))
    for flag, value in (("--width", "1000000000"), ("--views", "1000000000"), ("--fps", "1e308"),
                        ("--lighting-change", "1e308"), ("--lighting-change", "-5"), ("--start", "1000000000000")):
        d = fx.case_dir()
        out = d / "seq"
        cases.append(Case("absurd finite values", f"synth {flag} {value}",
                          ["synth", "--mocap", str(fx.amc), "--skeleton", str(fx.asf), "--frames", "2", "--views", "1",
                           "--width", "64", "--height", "48", "--out", str(out), flag, value], "refuse", (flag,),
                          absent=(out,)))
    for flag, value in (("--particles", "1000000000000"), ("--annealing-layers", "1000000000"),
                        ("--known-frames", "1000000")):
        d = fx.case_dir()
        cases.append(track_case("absurd finite values", f"track {flag} {value}", fx.seq, d, "refuse", (flag,),
                                flag, value))
    d = fx.case_dir()
    cases.append(track_case("absurd finite values", "track --gibbs-steps 10^12", fx.seq, d, "refuse",
                            ("--gibbs-steps", "gibbs"), "--model", str(fx.crbm), "--gibbs-steps", "1000000000000",
                            prior="crbm"))
    for flag, value in (("--hidden", "1000000000000"), ("--order", "1000000")):
        d = fx.case_dir()
        args = train_args(fx, d / "m.pt")
        args[args.index(flag) + 1] = value
        cases.append(Case("absurd finite values", f"train crbm {flag} {value}", args, "refuse",
                          (flag, flag.strip("-")), absent=(d / "m.pt",)))
    d = fx.case_dir()
    cases.append(Case("absurd finite values", "train gpdm --latent-dim 1000000",
                      train_args(fx, d / "m.pt", "--latent-dim", "1000000", prior="gpdm"), "refuse",
                      ("--latent-dim", "latent"), absent=(d / "m.pt",)))
    return cases


def _tiny_bvh(d: Path) -> Path:
    from tests.faults.test_bad_input_readers import TINY_BVH

    path = d / "tiny.bvh"
    path.write_text(TINY_BVH)
    return path


def huge_noise(fx: Fixtures) -> list[Case]:
    cases = []
    d = fx.case_dir()
    out = d / "seq"
    cases.append(Case("huge-noise options", "synth --noise 1e308",
                      ["synth", "--mocap", str(fx.amc), "--skeleton", str(fx.asf), "--frames", "2", "--views", "1",
                       "--width", "64", "--height", "48", "--noise", "1e308", "--out", str(out)], "refuse",
                      ("--noise",), absent=(out,)))
    for flag, prior, model in (("--root-noise", "zero-velocity", None), ("--root-noise", "crbm", fx.crbm),
                               ("--height-spread", "crbm", fx.crbm), ("--latent-noise", "gpdm", fx.gpdm),
                               ("--root-noise", "gpdm", fx.gpdm), ("--posture-gain", "crbm", fx.crbm),
                               ("--sharpness", "zero-velocity", None), ("--prior-scale", "zero-velocity", None)):
        d = fx.case_dir()
        extra = ("--model", str(model)) if model else ()
        cases.append(track_case("huge-noise options", f"track {prior} {flag} 1e308", fx.seq, d, "refuse",
                                (flag, flag.strip("-").replace("-", "_")), *extra, flag, "1e308", prior=prior))
    d = fx.case_dir()
    cases.append(Case("huge-noise options", "train crbm --history-noise 1e308",
                      train_args(fx, d / "m.pt", "--history-noise", "1e308"), "refuse",
                      ("--history-noise", "history noise"), absent=(d / "m.pt",)))
    return cases


def huge_header_images(fx: Fixtures) -> list[Case]:
    from tests.faults.test_bad_input_readers import _bmp_claiming, _png_claiming

    cases = []
    for label, where in (("frame", ("images", "cam0", "000000.png")), ("plate", ("background", "cam0.png"))):
        for cmd in ("track", "show"):
            d = fx.case_dir()
            seq = copy_sequence(fx, d)
            seq.joinpath(*where).write_bytes(_png_claiming(100000, 100000))
            make = track_case if cmd == "track" else show_case
            cases.append(make("huge-header images", f"{cmd}: png {label} claims 100000x100000", seq, d, "refuse",
                              (where[-1],)))
    d = fx.case_dir()
    bt = copy_bodytrack(fx, d)
    (bt / "CAM1" / "image0000.bmp").write_bytes(_bmp_claiming(200000, 200000))
    cases.append(show_case("huge-header images", "bodytrack bmp claims 200000x200000", bt, d, "refuse",
                           ("image0000.bmp",)))
    d = fx.case_dir()
    bt = copy_bodytrack(fx, d)
    (bt / "FG1" / "image0000.bmp").write_bytes(_bmp_claiming(200000, 200000))
    cases.append(track_case("huge-header images", "bodytrack mask claims 200000x200000", bt, d, "refuse",
                            ("image0000.bmp",)))
    return cases


def seeds(fx: Fixtures) -> list[Case]:
    cases = []
    for value in ("-1", str(2 ** 64), str(10 ** 30)):
        d = fx.case_dir()
        cases.append(track_case("seeds", f"track --seed {value}", fx.seq, d, "refuse", ("--seed", "seed"),
                                "--seed", value))
    for value in ("-5", str(2 ** 70)):
        d = fx.case_dir()
        out = d / "seq"
        cases.append(Case("seeds", f"synth --seed {value}",
                          ["synth", "--mocap", str(fx.amc), "--skeleton", str(fx.asf), "--frames", "2", "--views",
                           "1", "--width", "64", "--height", "48", "--seed", value, "--out", str(out)], "refuse",
                          ("--seed", "seed"), absent=(out,)))
    for value in (str(2 ** 64), "-3"):
        d = fx.case_dir()
        cases.append(Case("seeds", f"train --seed {value}", train_args(fx, d / "m.pt", "--seed", value), "refuse",
                          ("--seed", "seed"), absent=(d / "m.pt",)))
    d = fx.case_dir()
    cases.append(track_case("seeds", "track --seed 2^63-1 (largest allowed)", fx.seq, d, "accept", (),
                            "--seed", str(2 ** 63 - 1)))
    return cases


def mocap_values(fx: Fixtures) -> list[Case]:
    from tests.faults.test_bad_input_readers import TINY_BVH, amc_lines, asf_lines, write_lines

    cases = []
    for label, line in (("root 1e300", "root 1e300 1e300 1e300 0 0 0"), ("root NaN", "root nan 0 0 0 0 0"),
                        ("root angle 1e300", "root 0 0 0 1e300 0 0")):
        d = fx.case_dir()
        lines = amc_lines(5)
        k = next(i for i, s in enumerate(lines) if s.startswith("root"))
        lines[k] = line
        amc = write_lines(d / "07_01.amc", lines)
        cases.append(convert_case("AMC/BVH values", f"AMC {label}", amc, d, "refuse", ("07_01.amc",),
                                  "--skeleton", str(fx.asf)))
    for label, edit in (("BVH offset 1e300", lambda t: t.replace("OFFSET 0 50 0", "OFFSET 0 1e300 0")),
                        ("BVH frame time 0", lambda t: t.replace("Frame Time: 0.0083333", "Frame Time: 0")),
                        ("BVH frame value inf", lambda t: t.replace("\n1 90 2", "\ninf 90 2"))):
        d = fx.case_dir()
        bvh = d / "x.bvh"
        bvh.write_text(edit(TINY_BVH))
        cases.append(convert_case("AMC/BVH values", label, bvh, d, "refuse", ("x.bvh",)))
    d = fx.case_dir()
    lines = asf_lines()
    j = next(i for i, s in enumerate(lines) if s.strip().startswith("length") and i > 20)
    lines[j] = "     length 1e300"
    asf = write_lines(d / "07.asf", lines)
    cases.append(convert_case("AMC/BVH values", "ASF bone length 1e300", fx.amc, d, "refuse", ("07.asf",),
                              "--skeleton", str(asf)))
    return cases


def groundtruth_values(fx: Fixtures) -> list[Case]:
    cases = []
    gt = _groundtruth(fx.seq)
    for label, arrays in (("complex poses", {**gt, "poses": gt["poses"].astype(complex)}),
                          ("complex markers", {**gt, "markers": gt["markers"] + 1j}),
                          ("markers 1e308", {**gt, "markers": np.full_like(gt["markers"], 1e308)}),
                          ("poses 1e308", {**gt, "poses": np.full_like(gt["poses"], 1e308)}),
                          ("poses NaN", {**gt, "poses": gt["poses"] * np.nan}),
                          ("fps 1e308", {**gt, "fps": np.float64(1e308)})):
        d = fx.case_dir()
        seq = copy_sequence(fx, d)
        (seq / "groundtruth.npz").write_bytes(_npz_bytes(arrays))
        cases.append(track_case("ground-truth values", label, seq, d, "refuse", ("groundtruth.npz",)))
    return cases


def missing_calibration(fx: Fixtures) -> list[Case]:
    cases = []
    for cmd in ("show", "track"):
        d = fx.case_dir()
        bt = copy_bodytrack(fx, d)
        (bt / "CALIB" / "Camera3.cal").unlink()
        make = show_case if cmd == "show" else track_case
        cases.append(make("missing calibration", f"{cmd}: bodytrack CAM3 without Camera3.cal", bt, d, "refuse",
                          ("Camera3.cal",)))
    d = fx.case_dir()
    seq = copy_sequence(fx, d)
    rig = json.loads((seq / "cameras.json").read_text())
    rig["cameras"] = rig["cameras"][:1]
    (seq / "cameras.json").write_text(json.dumps(rig))
    cases.append(track_case("missing calibration", "own layout: images/cam1 not in cameras.json", seq, d, "refuse",
                            ("cam1", "cameras.json")))
    return cases


def other_skeleton(fx: Fixtures) -> list[Case]:
    cases = []
    foreign = SHARED_MOCAP / "02" / "02.asf"
    if foreign.exists():
        d = fx.case_dir()
        cases.append(convert_case("other subject's skeleton", "07_01.amc with 02.asf", fx.amc, d, "refuse",
                                  ("02.asf", "07_01.amc"), "--skeleton", str(foreign)))
        d = fx.case_dir()
        cases.append(Case("other subject's skeleton", "train with 02.asf for 07_01.amc",
                          ["train", "--prior", "crbm", "--mocap", str(fx.amc), "--skeleton", str(foreign), "--order",
                           "1", "--epochs", "1", "--hidden", "4", "--grow-from", "none", "--out", str(d / "m.pt")],
                          "refuse", ("02.asf", "07_01.amc"), absent=(d / "m.pt",)))
    d = fx.case_dir()
    renamed = d / "02.asf"
    shutil.copy(fx.asf, renamed)
    cases.append(convert_case("other subject's skeleton", "07_01.amc with subject 7's ASF named 02.asf", fx.amc, d,
                              "refuse", ("02.asf", "07_01.amc"), "--skeleton", str(renamed)))
    return cases


def output_paths(fx: Fixtures) -> list[Case]:
    """Every command's output where it cannot go: a file where a folder goes, a folder where a file goes, a path
    under a file, an unwritable place."""
    cases = []
    file_outputs = {  # command -> (args before the output, flag, suffix)
        "convert": (["convert", "--mocap", str(fx.amc), "--skeleton", str(fx.asf)], "--out", ".npz"),
        "train": (train_args(fx, Path("X"))[:-2], "--out", ".pt"),
        "show --out": (["show", str(fx.seq)], "--out", ".png"),
        "show --video": (["show", str(fx.seq)], "--video", ".mp4"),
        "track --video": (track_args(fx.seq, Path("OUT"))[:-2], "--video", ".mp4"),
    }
    for cmd, (args, flag, suffix) in file_outputs.items():
        for label in ("folder where a file goes", "path under a file", "unwritable place"):
            d = fx.case_dir()
            if label == "folder where a file goes":
                target = d / f"out{suffix}"
                target.mkdir()
            elif label == "path under a file":
                target = fx.a_file / f"out{suffix}"
            else:
                target = UNWRITABLE / f"out{suffix}"
            full = args + [flag, str(target)]
            if cmd == "track --video":
                full += ["--out", str(d / "out")]
            cases.append(Case("output paths", f"{cmd}: {label}", full, "refuse", (target.name, str(target), flag),
                              absent=(d / "out" / "estimates.npz",) if cmd == "track --video" else ()))
    for cmd in ("synth", "track"):
        for label in ("file where a folder goes", "path under a file", "unwritable place"):
            d = fx.case_dir()
            target = {"file where a folder goes": fx.a_file, "path under a file": fx.a_file / "out",
                      "unwritable place": UNWRITABLE / "out"}[label]
            if cmd == "synth":
                args = ["synth", "--mocap", str(fx.amc), "--skeleton", str(fx.asf), "--frames", "2", "--views", "1",
                        "--width", "64", "--height", "48", "--out", str(target)]
            else:
                args = track_args(fx.seq, target)
            cases.append(Case("output paths", f"{cmd}: {label}", args, "refuse", (target.name, str(target), "--out")))
    return cases


def synth_existing(fx: Fixtures) -> list[Case]:
    synth = ["synth", "--mocap", str(fx.amc), "--skeleton", str(fx.asf), "--views", "1", "--width", "64", "--height",
             "48"]
    cases = []
    d = fx.case_dir()
    seq = copy_sequence(fx, d)
    cases.append(Case("synth over an existing folder", "without --overwrite", synth + ["--frames", "2", "--out",
                                                                                      str(seq)], "refuse",
                      (seq.name, str(seq), "--overwrite"),
                      check=None))
    d = fx.case_dir()
    seq = copy_sequence(fx, d)

    def consistent(seq: Path = seq) -> str | None:
        images = sorted((seq / "images").rglob("*.png"))
        with np.load(seq / "groundtruth.npz") as z:
            frames = len(z["poses"])
        cams = json.loads((seq / "cameras.json").read_text())["cameras"]
        if frames != 2 or len(images) != 2 or len(cams) != 1:
            return f"inconsistent folder: {frames} ground-truth frames, {len(images)} images, {len(cams)} cameras"
        return None

    cases.append(Case("synth over an existing folder", "with --overwrite (must replace it whole)",
                      synth + ["--frames", "2", "--overwrite", "--out", str(seq)], "accept",
                      outputs=(seq / "groundtruth.npz",), check=consistent))
    d = fx.case_dir()
    other = d / "holiday_photos"
    other.mkdir()
    (other / "photo.jpg").write_bytes(b"not ours")
    cases.append(Case("synth over an existing folder", "a folder not ours, with --overwrite",
                      synth + ["--frames", "2", "--overwrite", "--out", str(other)], "refuse",
                      ("holiday_photos",), check=None))
    return cases


def harmless(fx: Fixtures) -> list[Case]:
    import cv2

    from tests.faults.test_bad_input_readers import amc_lines, write_lines

    cases = []
    d = fx.case_dir()
    seq = copy_sequence(fx, d)
    for png in list((seq / "images").rglob("*.png")) + list((seq / "background").glob("*.png")):
        cv2.imwrite(str(png), cv2.imread(str(png), cv2.IMREAD_GRAYSCALE))
    cases.append(track_case("harmless variants", "greyscale images and plates (track)", seq, d, "accept", ()))
    cases.append(show_case("harmless variants", "greyscale images and plates (show)", seq, fx.case_dir(), "accept",
                           ()))
    d = fx.case_dir()
    one = write_lines(d / "07_01.amc", amc_lines(1))
    cases.append(convert_case("harmless variants", "one-frame AMC", one, d, "accept", (), "--skeleton", str(fx.asf)))
    if fx.bvh is not None:
        d = fx.case_dir()
        tabbed = d / "tabbed.bvh"
        tabbed.write_text(fx.bvh.read_text().replace("  ", "\t").replace(" ", "\t"))
        cases.append(convert_case("harmless variants", "tabs in BVH", tabbed, d, "accept", ()))
        d = fx.case_dir()
        cases.append(convert_case("harmless variants", "one-frame BVH", small_bvh(d / "one.bvh", 1), d, "accept", ()))
    d = fx.case_dir()
    crlf = d / "07_01.amc"
    crlf.write_bytes(fx.amc.read_bytes().replace(b"\n", b"\r\n"))
    cases.append(convert_case("harmless variants", "AMC with CRLF line ends", crlf, d, "accept", (),
                              "--skeleton", str(fx.asf)))
    return cases


def controls(fx: Fixtures) -> list[Case]:
    """The untouched inputs: every command must succeed on them (else the corpus measures nothing)."""
    cases = []
    d = fx.case_dir()
    cases.append(convert_case("controls (valid input)", "convert", fx.amc, d, "accept", (), "--skeleton",
                              str(fx.asf)))
    for prior, model in (("zero-velocity", None), ("crbm", fx.crbm), ("gpdm", fx.gpdm)):
        d = fx.case_dir()
        extra = ("--model", str(model)) if model else ()
        cases.append(track_case("controls (valid input)", f"track {prior}", fx.seq, d, "accept", (), *extra,
                                prior=prior))
    cases.append(show_case("controls (valid input)", "show", fx.seq, fx.case_dir(), "accept", ()))
    cases.append(show_case("controls (valid input)", "show bodytrack", fx.bodytrack, fx.case_dir(), "accept", ()))
    for prior in ("crbm", "gpdm"):
        d = fx.case_dir()
        cases.append(Case("controls (valid input)", f"train {prior}", train_args(fx, d / "m.pt", prior=prior),
                          "accept", outputs=(d / "m.pt",)))
    return cases


CLASSES: list[Callable[[Fixtures], list[Case]]] = [
    controls, asf_hierarchy, not_utf8, byte_order_marks, deep_json, npz_files, meta_fields, crbm_models, gpdm_models,
    absurd_values, huge_noise, huge_header_images, seeds, mocap_values, groundtruth_values, missing_calibration,
    other_skeleton, output_paths, synth_existing, harmless,
]


# ---------------------------------------------------------------------------
# Running and classifying
# ---------------------------------------------------------------------------

def outputs_finite(paths: tuple[Path, ...]) -> str | None:
    """A problem with the outputs (missing or non-finite numbers), or None."""
    import torch

    for p in paths:
        if not p.exists():
            return f"{p.name} was not written"
        if p.suffix == ".npz":
            with np.load(p) as z:
                for k in z.files:
                    a = z[k]
                    if a.dtype.kind in "fc" and not np.all(np.isfinite(a)):
                        return f"{p.name}[{k}] has non-finite values"
        elif p.suffix == ".json":
            doc = json.loads(p.read_text())
            err = doc.get("metrics", {}).get("mpjpe_abs", {}).get("mean")
            if err is not None and not math.isfinite(err):
                return f"{p.name}: mpjpe_abs = {err}"
        elif p.suffix == ".pt":
            doc = torch.load(p, weights_only=True)
            if not isinstance(doc, dict):
                return f"{p.name} is not a model dictionary"
    return None


def classify(case: Case, rc: int | None, stderr: str, seconds: float) -> Outcome:
    lines = [s for s in stderr.replace("\r", "\n").splitlines() if s.strip()]
    if rc is None:
        return Outcome(case, "hang", seconds)
    if "Traceback" in stderr or rc not in (0, 2, 130):
        last = lines[-1] if lines else ""
        return Outcome(case, "traceback", seconds, f"exit {rc}: {last[:160]}")
    if rc == 2:
        left = [p for p in case.absent if p.exists()]
        if len(lines) != 1:
            kind = "buried refusal" if case.expect == "refuse" else "harmless refused"
            return Outcome(case, kind, seconds, f"{len(lines)} stderr lines: " + " | ".join(s[:80] for s in lines[:4]))
        if case.expect == "accept":
            return Outcome(case, "harmless refused", seconds, lines[0][:200])
        if left:
            return Outcome(case, "partial output", seconds, f"left {left[0]}: {lines[0][:120]}")
        if case.names and not any(n in lines[0] for n in case.names):
            return Outcome(case, "unnamed refusal", seconds, lines[0][:200])
        return Outcome(case, "clean refusal", seconds, lines[0][:200])
    if rc == 130:
        return Outcome(case, "traceback", seconds, "exit 130 (interrupted)")
    if case.expect == "refuse":
        return Outcome(case, "garbage accepted", seconds, (lines[-1][:160] if lines else "exit 0, nothing on stderr"))
    problem = outputs_finite(case.outputs) or (case.check() if case.check else None)
    if problem:
        return Outcome(case, "garbage accepted", seconds, problem)
    return Outcome(case, "success", seconds)


def run_case(case: Case, timeout: float) -> Outcome:
    env = {**os.environ, "OMP_NUM_THREADS": "1", "MKL_NUM_THREADS": "1", "OPENBLAS_NUM_THREADS": "1",
           "PYTHONWARNINGS": "default"}
    cmd = [sys.executable, "-m", "tracker", "--threads", "1", *case.args]
    t0 = time.perf_counter()
    try:
        r = subprocess.run(cmd, capture_output=True, text=True, timeout=timeout, env=env, cwd=REPO,
                           stdin=subprocess.DEVNULL)
    except subprocess.TimeoutExpired:
        return classify(case, None, "", time.perf_counter() - t0)
    return classify(case, r.returncode, r.stderr, time.perf_counter() - t0)


def report(outcomes: list[Outcome]) -> None:
    kinds = ["clean refusal", "success", "traceback", "hang", "buried refusal", "unnamed refusal", "garbage accepted",
             "harmless refused", "partial output"]
    classes = list(dict.fromkeys(o.case.cls for o in outcomes))
    short = {"clean refusal": "refused", "success": "success", "traceback": "traceb.", "hang": "hang",
             "buried refusal": "buried", "unnamed refusal": "unnamed", "garbage accepted": "garbage",
             "harmless refused": "harml.ref", "partial output": "partial"}
    width = max(len(c) for c in classes + ["total"])
    print(f"\n{'class':<{width}}  {'cases':>5}  " + "  ".join(f"{short[k]:>9}" for k in kinds))
    for cls in classes + ["total"]:
        mine = [o for o in outcomes if cls in ("total", o.case.cls)]
        counts = [sum(o.kind == k for o in mine) for k in kinds]
        print(f"{cls:<{width}}  {len(mine):>5}  " + "  ".join(f"{c:>9}" for c in counts))
    failures = [o for o in outcomes if o.kind != OK_OUTCOMES[o.case.expect]]
    print(f"\n{len(failures)} failure(s) of {len(outcomes)} cases")
    for o in failures:
        print(f"- [{o.kind}] {o.case.cls}: {o.case.name}: {o.detail}")


def main(argv: list[str] | None = None) -> int:
    p = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    p.add_argument("--only", default=None, help="comma-separated class functions to run (e.g. gpdm_models,seeds)")
    p.add_argument("--timeout", type=float, default=60.0, help="seconds per case before it counts as a hang")
    p.add_argument("--keep", default=None, help="build the corpus in this folder and keep it")
    p.add_argument("--verbose", action="store_true", help="print every case's outcome as it finishes")
    args = p.parse_args(argv)
    chosen = CLASSES if not args.only else [f for f in CLASSES if f.__name__ in args.only.split(",")]
    root = Path(args.keep) if args.keep else Path(tempfile.mkdtemp(prefix="bad-input-corpus-"))
    root.mkdir(parents=True, exist_ok=True)
    t0 = time.perf_counter()
    try:
        fx = build_fixtures(root)
        print(f"fixtures built in {time.perf_counter() - t0:.0f} s under {root}", flush=True)
        outcomes = []
        for make in chosen:
            for case in make(fx):
                outcome = run_case(case, args.timeout)
                outcomes.append(outcome)
                if args.verbose or outcome.kind != OK_OUTCOMES[case.expect]:
                    print(f"  {outcome.kind:<16} {outcome.seconds:5.1f} s  {case.cls}: {case.name}"
                          + (f"  ({outcome.detail[:100]})" if outcome.kind != OK_OUTCOMES[case.expect] else ""),
                          flush=True)
        report(outcomes)
        print(f"\n{len(outcomes)} cases in {time.perf_counter() - t0:.0f} s")
    finally:
        if not args.keep:
            shutil.rmtree(root, ignore_errors=True)
    failures = sum(o.kind != OK_OUTCOMES[o.case.expect] for o in outcomes)
    return 1 if failures else 0


if __name__ == "__main__":
    sys.exit(main())

"""A tracked run's poses out of the toolkit: as BVH (a skeleton of the body model's links) and TRC (the
markers), and compared with a reference reconstruction in a TRC file. ``pose-tracker export`` and
``pose-tracker compare-trc`` are these calls; ``pose-tracker capture`` writes its BVH and TRC with them.
"""
from __future__ import annotations

from pathlib import Path
from typing import Callable

from tracker.core.errors import InputError

__all__ = ["export_poses", "export_run", "compare_run_to_trc"]


def export_poses(seq, poses, *, bvh: str | Path | None = None, trc: str | Path | None = None,
                 unit: str = "m", on_written: Callable[[str], None] | None = None) -> list[str]:
    """Write ``poses`` ``T x D`` of the sequence ``seq``'s body model at its frame rate: as BVH at ``bvh`` (y up,
    lengths in ``unit``: ``m``, ``cm`` or ``mm``) and the body's markers as TRC at ``trc`` (y up, metres);
    returns one line per file written, each also given to ``on_written`` as soon as its file is."""
    from data_tools.motion.bvh_export import write_bvh
    from data_tools.motion.trc import write_trc
    from tracker.core.kinematics import markers

    fps = seq.fps or 60.0
    lines = []
    if bvh:
        write_bvh(bvh, seq.model, poses, fps, unit=unit)
        lines.append(f"{len(poses)} frames at {fps:g} Hz -> {bvh} (BVH, y up, {unit})")
        if on_written is not None:
            on_written(lines[-1])
    if trc:
        write_trc(trc, seq.model.marker_names, markers(seq.model, poses), fps)
        lines.append(f"{len(poses)} frames at {fps:g} Hz -> {trc} (TRC, y up, m)")
        if on_written is not None:
            on_written(lines[-1])
    return lines


def export_run(run: str | Path, *, bvh: str | Path | None = None, trc: str | Path | None = None,
               unit: str = "m", sequence: str | Path | None = None, overwrite: bool = False,
               overwrite_flag: str = "overwrite=True", on_written: Callable[[str], None] | None = None) -> list[str]:
    """Write the poses of the tracked run in the folder ``run`` (``estimates.npz``, ``result.json``) as
    :func:`export_poses` does; ``sequence`` is the tracked sequence (default the one ``result.json`` names: its
    body shape and frame rate). Existing files are refused unless ``overwrite``."""
    from data_tools.io.files import check_output_file
    from data_tools.sequences.estimates import read_poses_file
    from tracker.app.run_folder import finished_run, run_sequence

    if not bvh and not trc:
        raise InputError("nothing to write: give a BVH file (--bvh) and/or a TRC file (--trc)")
    for path, flag, ext in ((bvh, "--bvh", ".bvh"), (trc, "--trc", ".trc")):
        if path:
            check_output_file(path, flag, (ext,), new=not overwrite, overwrite_flag=overwrite_flag)
    estimates, result = finished_run(run)
    seq = run_sequence(result, sequence, run)
    return export_poses(seq, read_poses_file(estimates, "estimates", seq.model), bvh=bvh, trc=trc, unit=unit,
                        on_written=on_written)


def compare_run_to_trc(run: str | Path, reference: str | Path, offset: int | None = None):
    """The distance of the tracked run in ``run`` to the reference reconstruction ``reference`` (a TRC file)
    after one rigid alignment (:func:`data_tools.sequences.reference.compare_to_trc`); ``offset`` is the reference frame
    of the run's first frame (default: the first video frame the sequence was imported from, else 0)."""
    from data_tools.io.checks import load_npz
    from data_tools.sequences.reference import compare_to_trc, reference_offset
    from tracker.app.run_folder import finished_run, run_sequence

    estimates, result = finished_run(run)
    markers = load_npz(estimates, "estimates", ("markers",))["markers"]
    if offset is None:
        offset = reference_offset(run_sequence(result, None, run).meta) if result.get("sequence") else 0
    return compare_to_trc(markers, reference, offset=offset)

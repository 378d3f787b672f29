"""Ctrl-C before the filter's first frame (while the sequence is read or the priors are prepared) is one line,
exit status 130, and leaves nothing behind: the same command then runs without --overwrite."""
from tracker.app import api, cli


def test_ctrl_c_before_the_first_frame_leaves_nothing_behind(synthetic_walk, tmp_path, monkeypatch, capsys):
    out = tmp_path / "run"
    argv = ["--threads", "1", "track", str(synthetic_walk.root), "--prior", "zero-velocity", "--particles", "50",
            "--annealing-layers", "1", "--out", str(out)]

    def interrupted(*args, **kwargs):
        raise KeyboardInterrupt

    monkeypatch.setattr(api, "track", interrupted)
    capsys.readouterr()
    assert cli.main(argv) == 130
    err = [line for line in capsys.readouterr().err.splitlines() if line.strip()]
    assert len(err) == 1 and "interrupted" in err[0] and "Traceback" not in err[0], err
    assert not out.exists() or not any(out.iterdir())
    monkeypatch.undo()
    assert cli.main(argv) == 0 and (out / "result.json").is_file()

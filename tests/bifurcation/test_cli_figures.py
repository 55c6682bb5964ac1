"""``nsbench bifurcation`` end to end: diagram, locus and portrait figures, candidates, comparison."""

from __future__ import annotations

import pandas as pd

from nsbench.cli import main


def test_bifurcation_command_writes_figures(tmp_path, capsys):
    out = tmp_path / "b"
    code = main(["bifurcation", "two-dof", "--case", "1", "--sweep", "v0=0.1:0.2:6", "--transient", "300",
                 "--record", "20", "--workers", "1", "--out", str(out), "--portrait", "0.1",
                 "--no-progress"])
    assert code == 0
    for stem in ("diagram", "locus_v0_0.1", "portrait_v0_0.1"):
        for fmt in ("png", "svg", "pdf"):
            path = out / f"{stem}.{fmt}"
            assert path.exists() and path.stat().st_size > 1000, path
    feats = pd.read_csv(out / "features.csv")
    assert len(feats) == 6 and {"period", "pure_sliding", "block1_sticks"} <= set(feats.columns)
    assert "diagram ->" in capsys.readouterr().out


def test_several_integrators_are_compared(tmp_path):
    out = tmp_path / "c"
    code = main(["bifurcation", "two-dof", "--case", "2", "--sweep", "F=0.2:0.4:3", "--transient", "200",
                 "--record", "8", "--workers", "1", "--out", str(out), "--integrator", "exact",
                 "--integrator", "ofapi", "--formats", "png", "--no-progress"])
    assert code == 0
    text = (out / "compare.md").read_text()
    assert "ofapi" in text and "Hausdorff" in text
    agree = pd.read_csv(out / "agreement.csv")
    # OFAPI at its default tolerance (1e-13) on periodic stroboscopic points: within 1e-9 of the closed form
    assert (agree["ofapi"] < 1e-9).all()


def test_bad_input_exits_2(tmp_path, capsys):
    assert main(["bifurcation", "two-dof", "--sweep", "v0=0.1:0.2", "--out", str(tmp_path / "x")]) == 2
    assert main(["bifurcation", "two-dof", "--sweep", "nope=0.1:0.2:3", "--out", str(tmp_path / "y")]) == 2
    assert main(["bifurcation", "two-dof", "--case", "3", "--sweep", "v0=0.1:0.2:3",
                 "--integrator", "exact", "--out", str(tmp_path / "z"), "--no-progress"]) == 2
    err = capsys.readouterr().err
    assert err.count("nsbench: error:") == 3

"""Report figures: method families come from capabilities (a plug-in gets its own colour and marker), the
runtime distributions (COCO style) and legends beside the data, on planted rows."""

from __future__ import annotations

import re
from dataclasses import replace

import matplotlib
import numpy as np
import pytest
from matplotlib.colors import to_rgba

from nsbench import registry
from nsbench.bench import figures
from nsbench.bench.figures import FAMILIES, _styles, family
from nsbench.bench.storage import to_frame
from nsbench.bench.tables import fixed_target
from nsbench.integrators.henon_rk4 import HenonRK4
from nsbench.integrators.scipy_ import ScipyIntegrator
from tests.legends import overlaps

matplotlib.use("Agg")


@pytest.fixture
def kept(monkeypatch):
    """The figures handed to ``_save``, kept open (nothing written); each call returns its index."""
    out = []
    monkeypatch.setattr(
        figures, "_save", lambda fig, folder, name, title, caption: out.append((fig, name, caption)) or len(out) - 1
    )
    yield out
    import matplotlib.pyplot as plt

    for fig, _, _ in out:
        plt.close(fig)


def _row(problem, integrator, level, wall, nfev, err, ok=True):
    return {
        "case_id": f"{problem}-{integrator}-{level}",
        "problem_label": problem,
        "integrator": integrator,
        "level": level,
        "status": "success",
        "reference": "exact",
        "reference_status": "ok",
        "sequence_ok": ok,
        "switch_err_max": err,
        "wall_time": wall,
        "nfev": nfev,
        "options": "{}",
        "event_t": [1.0, 2.0, 3.0],
        "event_err": [err, -err, err / 2],
        "wall_time_min": wall * 0.9,
        "wall_time_max": wall * 1.1,
    }


@pytest.fixture
def frame():
    # two problems x three targets = six pairs; costs and errors planted
    rows = []
    for p in ("two-dof/1", "two-dof/2"):
        rows += [
            _row(p, "exact", 0, 0.001, 0, 0.0),
            _row(p, "a", 0, 0.01, 1000, 1e-7),
            _row(p, "a", 1, 0.04, 4000, 1e-10),
            _row(p, "a", 2, 0.1, 9000, 1e-13),
            _row(p, "b", 0, 0.02, 500, 1e-7),
            _row(p, "b", 1, 0.3, 6000, 1e-8),
        ]
    rows.append(_row("two-dof/2", "b", 2, 0.5, 8000, 1e-10, ok=False))  # a wrong sequence never solves
    return to_frame(rows)


def test_runtime_distribution_counts_the_pairs_each_method_solves(frame, kept):
    long = fixed_target(frame, (1e-6, 1e-9, 1e-12))
    styles = figures._styles(["a", "b", "exact"])
    assert figures.runtime_distribution(long[long["integrator"] != "exact"], styles, None) == 0
    fig, name, caption = kept[0]
    assert name == "runtime_distribution" and "6 (problem, target) pairs (2 problems, 3" in caption
    left, right = fig.axes[:2]
    curves = {line.get_label(): line for line in left.get_lines() if not line.get_label().startswith("_")}
    assert set(curves) == {"a", "b"}
    # a reaches 1e-6 at 0.01 s, 1e-9 at 0.04 s, 1e-12 at 0.1 s on both problems: all 6 pairs
    x, y = curves["a"].get_data()
    assert y[-1] == pytest.approx(1.0) and x[-1] == pytest.approx(0.1)
    # b reaches only 1e-6 (at 0.02 s) on both problems: 2 of 6 pairs
    x, y = curves["b"].get_data()
    assert y[-1] == pytest.approx(2 / 6) and np.allclose(x[1:], [0.02, 0.02])
    nfev = {line.get_label(): line for line in right.get_lines() if not line.get_label().startswith("_")}
    assert nfev["a"].get_data()[0][-1] == pytest.approx(9000)
    assert overlaps(fig) == []


def test_nothing_to_grade_draws_nothing(frame):
    long = fixed_target(frame.assign(reference_status="no reference available"), (1e-6,))
    assert figures.runtime_distribution(long, figures._styles(["a", "b", "exact"]), None) is None


@pytest.mark.parametrize("draw", ["work_precision", "event_error_along"])
def test_legends_are_beside_the_data(frame, kept, draw):
    styles = figures._styles(sorted(frame["integrator"].unique()))
    group = frame[frame["problem_label"] == "two-dof/1"]
    if draw == "work_precision":
        figures.work_precision(group, "two-dof/1", "wall_time", styles, None)
    else:
        figures.event_error_along(group, "two-dof/1", styles, None)
    fig = kept[0][0]
    assert (fig.legends or any(ax.get_legend() for ax in fig.axes)) and overlaps(fig) == []


class NamedLikeScipy(HenonRK4):
    """A plug-in whose name starts like scipy's adapters but that locates events its own way."""

    name = "scipy-lookalike"
    capabilities = replace(HenonRK4.capabilities, event_location="bisection")


class DenseOutputPlugin(HenonRK4):
    """A plug-in that locates events on a dense output, as scipy's adapters do."""

    name = "zz-dense"
    capabilities = replace(HenonRK4.capabilities, event_location="dense-output-root")


class OwnWay(HenonRK4):
    name = "own-way"
    capabilities = replace(HenonRK4.capabilities, event_location="chebyshev-bisection")


@pytest.fixture
def plugins():
    for cls in (NamedLikeScipy, DenseOutputPlugin, OwnWay):
        registry.register("integrators", cls.name, cls)
    yield
    for cls in (NamedLikeScipy, DenseOutputPlugin, OwnWay):
        registry.unregister("integrators", cls.name)


def test_families_come_from_capabilities_not_names(plugins):
    assert issubclass(registry.load("integrators", "scipy-rk45"), ScipyIntegrator)
    assert family("scipy-rk45") == family("scipy-lsoda") == family("zz-dense") == "dense output"
    assert family("cvode-bdf") == family("ida") == "solver root finding"
    assert family("heyoka-q") == "Taylor" and family("ofapi") == family("mcpi") == "collocation"
    assert family("exact") == family("exact-mp") == family("reference") == "reference"
    assert family("scipy-lookalike") == "bisection"  # its name says scipy, its capabilities do not
    assert family("not-registered-here") == "other"


def test_a_plugin_gets_its_own_colour_and_marker(plugins):
    from nsbench import list_integrators

    names = sorted(list_integrators())
    styles = _styles(names)
    pairs = {n: (to_rgba(st["color"]), st["marker"]) for n, st in styles.items()}
    assert len(set(pairs.values())) == len(names)  # no two integrators look alike
    family_maps = dict(FAMILIES)
    own = [n for n in names if family(n) not in family_maps]
    assert set(own) >= {"scipy-lookalike", "own-way"}
    colours = [to_rgba(styles[n]["color"]) for n in names]
    for n in own:  # a colour nobody else has
        assert colours.count(to_rgba(styles[n]["color"])) == 1, n
    # a plug-in in a known family shares its hue, told apart by shade and marker
    dense = [n for n in names if family(n) == "dense output"]
    assert "zz-dense" in dense and len({styles[n]["marker"] for n in dense}) == len(dense)


@pytest.mark.parametrize(
    "value, label",
    [(1e-6, "10⁻⁶"), (1.0, "1"), (10.0, "10"), (1000.0, "1000"), (1e4, "10⁴"), (2e-6, "2e-06"), (0.0, "")],
)
def test_log_ticks_are_plain_text(value, label):
    assert figures.plain_log_label(value) == label


def test_no_log_axis_label_is_mathtext(tmp_path):
    import matplotlib.pyplot as plt

    fig, (wide, narrow, base2) = plt.subplots(1, 3)
    wide.loglog([1e-12, 1e-3], [1e-4, 10.0])
    narrow.semilogy([0.0, 1.0], [2e-6, 5e-6])  # less than a decade: labelled by its minor ticks
    base2.plot([2, 16], [1.0, 1e3])
    base2.set_xscale("log", base=2)
    figures._plain_log_ticks(fig)
    fig.canvas.draw()
    labels = [t.get_text() for ax in fig.axes for t in ax.get_xticklabels() + ax.get_yticklabels(minor=True)]
    labels += [t.get_text() for ax in fig.axes for t in ax.get_yticklabels()]
    assert labels and not any("$" in t for t in labels)
    assert any(re.fullmatch("10⁻[⁰¹²³⁴⁵⁶⁷⁸⁹]+", t) for t in labels)  # the wide axis' decades
    assert "2×10⁻⁶" in labels and "16" in labels
    plt.close(fig)


def test_minor_ticks_only_on_log_axes_of_fewer_than_three_decades():
    import matplotlib.pyplot as plt

    fig, (wide, two, narrow) = plt.subplots(1, 3)
    wide.semilogy([0.0, 1.0], [1e-16, 1e-2])
    two.semilogy([0.0, 1.0], [1e-6, 5e-5])
    narrow.semilogy([0.0, 1.0], [2e-6, 5e-6])
    figures._plain_log_ticks(fig)
    fig.canvas.draw()
    assert wide.yaxis.get_minorticklocs().size == 0 and wide.yaxis.get_majorticklocs().size > 0
    assert two.yaxis.get_minorticklocs().size > 0 and narrow.yaxis.get_minorticklocs().size > 0
    plt.close(fig)


def test_a_large_report_draws_its_figures_in_other_processes_the_same_files(tmp_path):
    """Drawn in a pool of processes (spawned: nothing of this process inherited), the per-problem figures are the
    serial ones, in report order, in the formats asked for."""
    rows = []
    for p in ("one-dof/1", "two-dof/1", "two-dof/2", "two-dof/3", "two-dof/4", "two-dof/5"):
        rows += [
            _row(p, "exact", 0, 0.001, 0, 0.0),
            _row(p, "a", 0, 0.01, 1000, 1e-7),
            _row(p, "a", 1, 0.04, 4000, 1e-10),
        ]
    frame = to_frame(rows)
    serial = figures.report_figures(frame, tmp_path / "one", processes=1)
    assert len(serial) >= figures.PARALLEL_FIGURES
    with figures.saving_as(["png", "svg"]):
        pooled = figures.report_figures(frame, tmp_path / "pool", processes=2)
    assert [f.name for f in pooled] == [f.name for f in serial]
    assert all(f.png.is_file() and f.svg is not None and f.svg.is_file() for f in pooled)


def test_the_families_hues_are_told_apart():
    import itertools

    from matplotlib.colors import to_rgb

    bases = {fam: np.array(to_rgb(colour)) for fam, colour in FAMILIES}
    # every two families' colours at least a quarter of the RGB cube's edge apart (the closest pair,
    # reference grey against time-stepping brown, is 0.265; collocation and time-stepping were 0.056)
    for (a, ca), (b, cb) in itertools.combinations(bases.items(), 2):
        assert np.linalg.norm(ca - cb) > 0.25, (a, b)
    styles = _styles(["ofapi", "moreau-jean", "mcpi", "exact"])
    apart = np.linalg.norm(
        np.array(to_rgba(styles["ofapi"]["color"])[:3]) - to_rgba(styles["moreau-jean"]["color"])[:3]
    )
    assert apart > 0.3


def test_a_configuration_is_named_by_its_options_not_its_level():
    from nsbench.bench.labels import configuration, options_text

    assert configuration("henon-rk4", '{"h": 0.0001}') == "henon-rk4 (h=0.0001)"
    assert configuration("henon-rk4", {"h": 0.0001}) == "henon-rk4 (h=0.0001)"
    assert configuration("exact", "{}") == "exact"
    assert options_text('{"rtol": 1e-09, "atol": 1e-11}') == "rtol=1e-09, atol=1e-11"

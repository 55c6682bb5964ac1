"""Report figures: method families come from capabilities, and a plug-in gets its own colour and marker."""

from __future__ import annotations

from dataclasses import replace

import pytest
from matplotlib.colors import to_rgba

from nsbench import registry
from nsbench.bench.figures import FAMILIES, _styles, family
from nsbench.integrators.henon_rk4 import HenonRK4
from nsbench.integrators.scipy_ import ScipyIntegrator


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
    assert family("scipy-lookalike") == "bisection"          # its name says scipy, its capabilities do not
    assert family("not-registered-here") == "other"


def test_a_plugin_gets_its_own_colour_and_marker(plugins):
    from nsbench import list_integrators

    names = sorted(list_integrators())
    styles = _styles(names)
    pairs = {n: (to_rgba(st["color"]), st["marker"]) for n, st in styles.items()}
    assert len(set(pairs.values())) == len(names)            # no two integrators look alike
    family_maps = dict(FAMILIES)
    own = [n for n in names if family(n) not in family_maps]
    assert set(own) >= {"scipy-lookalike", "own-way"}
    colours = [to_rgba(styles[n]["color"]) for n in names]
    for n in own:                                             # a colour nobody else has
        assert colours.count(to_rgba(styles[n]["color"])) == 1, n
    # a plug-in in a known family shares its hue, told apart by shade and marker
    dense = [n for n in names if family(n) == "dense output"]
    assert "zz-dense" in dense and len({styles[n]["marker"] for n in dense}) == len(dense)

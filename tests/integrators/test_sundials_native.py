"""The native SUNDIALS path: the binding (the wheel's libraries, the version, the fallback), what a solver owns,
and the compiled loop against the per-arc path and the core's checks."""

from __future__ import annotations

import ctypes
import gc
import re

import numpy as np
import pytest

import nsbench
from nsbench.integrators import _sundials_capi as capi
from nsbench.integrators import _sundials_kernels as sk

SUNDIALS = ["cvode-adams", "cvode-bdf", "ida"]
needs_binding = pytest.mark.skipif(capi.unavailable() is not None, reason=f"no native binding: {capi.unavailable()}")


@pytest.fixture(scope="module")
def case2():
    return nsbench.get_problem("two-dof", case=2)


# ---------------------------------------------------------------------- the binding
@needs_binding
def test_the_wheel_libraries_and_the_version_are_the_pinned_ones():
    # auditwheel's names (a hash, the SUNDIALS version), the version SUNDIALS reports being the one
    # scikit-sundae was built with, and the index type of that build (32-bit in the wheel)
    from sksundae import SUNDIALS_VERSION

    b = capi.load()
    for name in capi.LIBRARIES:
        assert re.fullmatch(rf"libsundials_{name}-[0-9a-f]{{8}}\.so\.7\.\d+\.\d+", b.paths[name].name), b.paths[name]
    assert b.version == tuple(int(v) for v in SUNDIALS_VERSION.split("."))
    assert b.version[0] == capi.MAJOR == 7
    assert b.index is ctypes.c_int32
    assert np.all(b.table != 0)  # every function the loop calls was found
    assert b.flag_name("cvode", -1) == "CV_TOO_MUCH_WORK" and b.flag_name("ida", -4) == "IDA_CONV_FAIL"


def test_a_library_missing_or_found_twice_is_refused(tmp_path):
    with pytest.raises(capi.BindingUnavailable, match="no libsundials_cvode"):
        capi.find_library("cvode", [tmp_path])
    (tmp_path / "libsundials_cvode-0123abcd.so.7.9.0").write_bytes(b"")
    (tmp_path / "libsundials_cvodes-0123abcd.so.7.9.0").write_bytes(b"")  # another library: not a match
    assert capi.find_library("cvode", [tmp_path]).name == "libsundials_cvode-0123abcd.so.7.9.0"
    (tmp_path / "libsundials_cvode-4567cdef.so.7.10.0").write_bytes(b"")
    with pytest.raises(capi.BindingUnavailable, match="several libsundials_cvode"):
        capi.find_library("cvode", [tmp_path])


@needs_binding
@pytest.mark.parametrize("name", SUNDIALS)
def test_a_binding_that_does_not_load_falls_back_in_one_line(name, monkeypatch, case2):
    # the libraries of another SUNDIALS major version: the per-arc path runs, and the result says why in
    # one line; forcing the native path is refused before the run
    monkeypatch.setattr(capi, "_BINDING", {})
    monkeypatch.setattr(capi, "_version", lambda core: (8, 0, 0))
    res = nsbench.simulate(case2, name, 20.0)
    assert res.ok and res.loop == "per-arc"
    assert res.loop_note == (
        "the native SUNDIALS binding does not load: scikit-sundae ships SUNDIALS 8.0.0; "
        "the native path is written for SUNDIALS 7"
    )
    assert "\n" not in res.loop_note
    with pytest.raises(nsbench.ConfigError, match="loop = 'native' cannot run two-dof: the native SUNDIALS binding"):
        nsbench.simulate(case2, name, 20.0, options={"loop": "native"})


# ---------------------------------------------------------------------- the same runs as the per-arc path
@needs_binding
@pytest.mark.parametrize("name", SUNDIALS)
def test_native_and_per_arc_runs_are_the_same(name, case2):
    # The same solver settings, formulas and steps: every event, section hit and state at a requested time
    # equal to the last bit, and the same counters (the states come from the same interpolant, CVodeGetDky).
    from nsbench.sections import peaks, stroboscopic

    grid = np.linspace(0.0, 300.0, 301)
    secs = [peaks(case2), stroboscopic(case2)]
    native = nsbench.simulate(case2, name, 300.0, t_eval=grid, sections=secs)
    per_arc = nsbench.simulate(case2, name, 300.0, t_eval=grid, sections=secs, options={"loop": "per-arc"})
    assert native.loop == "native" and per_arc.loop == "per-arc" and native.ok and per_arc.ok
    assert len(native.events) > 150 and native.events.equals(per_arc.events)
    assert len(native.sections) > 50 and native.sections.equals(per_arc.sections)
    assert native.trajectory.equals(per_arc.trajectory)
    for field in ("nfev", "njev", "nsteps", "n_events"):
        assert getattr(native.counters, field) == getattr(per_arc.counters, field)
    assert native.counters.extra["root_returns"] == per_arc.counters.extra["root_returns"]
    assert native.counters.extra["midpoint_checks"] >= native.counters.nsteps  # every step checked


@needs_binding
@pytest.mark.parametrize("name", SUNDIALS)
def test_a_hit_stop_and_the_stop_rule_end_the_run_as_per_arc(name, case2):
    from nsbench.hybrid.run import run_hybrid
    from nsbench.sections import peaks

    for options in ({}, {"loop": "per-arc"}):
        integ = nsbench.get_integrator(name, **options)
        integ.setup(case2)
        raw = run_hybrid(case2, integ, 300.0, sections=[peaks(case2)], hit_from=50.0, hit_stop=7)
        assert raw.stopped and raw.n_hits == 7 and raw.records.hits.t[0] >= 50.0
        raw2 = run_hybrid(case2, integ, 300.0, record_from=100.0, stop_kind="slip", stop_count=3)
        assert raw2.stopped and raw2.records.ev_kind[: raw2.n_events].tolist().count(1) == 3
        if not options:
            native = (raw.t, raw.records.hits.t[:7].copy(), raw2.t, raw2.records.ev_t[: raw2.n_events].copy())
            assert raw.loop == "native"
    assert raw.loop == "per-arc"
    assert native[0] == raw.t and np.array_equal(native[1], raw.records.hits.t[:7])
    assert native[2] == raw2.t and np.array_equal(native[3], raw2.records.ev_t[: raw2.n_events])


# ---------------------------------------------------------------------- the core's checks, on the solver's steps
@needs_binding
@pytest.mark.parametrize("name", SUNDIALS)
def test_storms_and_budgets_end_a_native_run_with_the_core_statuses(name, case2):
    # the core's settle rule and budgets: an accumulation of events within the storm span, the event budget,
    # the step budget (checked before every step: never exceeded)
    storm = nsbench.simulate(case2, name, 300.0, zeno_events=3, zeno_span=5.0)
    assert storm.loop == "native" and storm.status is nsbench.Status.EVENT_STORM
    assert "spread over time" in storm.message
    per_arc = nsbench.simulate(case2, name, 300.0, zeno_events=3, zeno_span=5.0, options={"loop": "per-arc"})
    assert per_arc.status is storm.status and per_arc.events.equals(storm.events)
    events = nsbench.simulate(case2, name, 300.0, max_events=10)
    assert events.status is nsbench.Status.BUDGET_EXHAUSTED and len(events.events) == 10
    assert "event budget of 10 events" in events.message
    steps = nsbench.simulate(case2, name, 300.0, max_steps=50)
    assert steps.status is nsbench.Status.BUDGET_EXHAUSTED and steps.counters.nsteps == 50
    assert "50 steps used" in steps.message


@needs_binding
@pytest.mark.parametrize("name", SUNDIALS)
def test_a_solver_failure_is_a_status_naming_sundials_flag(name, case2):
    # a relative tolerance below what double precision can meet: SUNDIALS refuses the step; the run ends as
    # an integrator failure whose message is SUNDIALS' flag (no traceback, nothing printed by SUNDIALS)
    res = nsbench.simulate(case2, name, 300.0, options={"rtol": 1e-20, "atol": 1e-30})
    assert res.loop == "native" and res.status is nsbench.Status.INTEGRATOR_FAILURE
    assert re.fullmatch(r"SUNDIALS: (CV|IDA)_[A-Z_]+ \(flag -\d+\) at t = \S+", res.message), res.message


@needs_binding
@pytest.mark.parametrize("name", SUNDIALS)
def test_a_non_finite_start_ends_the_run_without_a_crash(name, case2):
    # simulate refuses such a start (ConfigError); the core's entry for sweeps and orbits does not check it
    from nsbench.hybrid.run import run_hybrid

    integ = nsbench.get_integrator(name)
    integ.setup(case2)
    raw = run_hybrid(case2, integ, 10.0, y0=np.array([np.nan, 0.0, 0.0, 0.0]))
    assert raw.loop == "native" and raw.status is nsbench.Status.INTEGRATOR_FAILURE
    assert re.fullmatch(r"SUNDIALS: (CV|IDA)_CONV_FAIL(URE)? \(flag -4\) at t = 0", raw.message), raw.message


@needs_binding
@pytest.mark.parametrize("name", SUNDIALS)
def test_a_crossing_the_solver_steps_over_is_found_on_its_steps(name, monkeypatch):
    # Root finding switched off in the solver (as if it never saw a guard change sign): the first event of
    # case 1 (block 2's slip ends at t = 0.10025, exact) is stepped over, the velocity guard goes to its wrong
    # side and, in the frozen slip, comes back. The per-step check sees it at the middle of a step right
    # after the crossing; with check_points=0 no state at a requested time would.
    from nsbench.integrators import _sundials_native as native

    problem = nsbench.get_problem("two-dof", case=1)
    t_first = float(nsbench.simulate(problem, "exact", 1.0, check_points=0).events["t"].iloc[0])
    init = native.NativeSolver.__init__

    def blind(self, *args, **kwargs):
        init(self, *args, **kwargs)
        lib, prefix = ("cvode", "CVode") if self.kind == native.CVODE else ("ida", "IDA")
        root_init = getattr(self.binding.libs[lib], f"{prefix}RootInit")
        root_init.argtypes = [ctypes.c_void_p, ctypes.c_int, ctypes.c_void_p]
        assert root_init(int(self.bundle.h[native.H_MEM]), 0, None) == 0

    monkeypatch.setattr(native.NativeSolver, "__init__", blind)
    res = nsbench.simulate(problem, name, 50.0, check_points=0)
    assert res.loop == "native" and res.status is nsbench.Status.EVENT_MISSED, res.message
    assert "stepped over a crossing" in res.message
    assert t_first < res.t_final < t_first + 0.5  # the first sighting, inside a step after the crossing


# ---------------------------------------------------------------------- what a solver owns
@needs_binding
@pytest.mark.parametrize("name", SUNDIALS)
def test_a_solver_frees_what_it_owns(name, case2):
    from nsbench.integrators import _sundials_native as native
    from nsbench.sections import peaks

    integ = nsbench.get_integrator(name)
    nsbench.simulate(case2, integ, 10.0)
    nsbench.simulate(case2, integ, 10.0, sections=[peaks(case2)])
    solvers = list(integ._native.values())
    held = 8 if name == "ida" else 7  # the context, 3 vectors (IDA: 4), the matrix, the linear solver, the memory
    assert len(solvers) == 2 and all(s.own.alive == held for s in solvers)
    integ.setup(case2)  # the same problem: they stay
    assert all(s.own.alive == held for s in solvers) and len(integ._native) == 2
    integ.setup(nsbench.get_problem("two-dof", case=1))  # another problem: the solvers go
    assert all(s.own.alive == 0 for s in solvers) and not integ.__dict__.get("_native")
    with pytest.raises(RuntimeError, match="freed"):
        solvers[0].prepare(np.zeros(0))
    # one dropped without close() is freed when collected
    kind = native.IDA if name == "ida" else native.CVODE
    solver = native.NativeSolver(kind, case2, "BDF", 1e-8, 1e-10, 0.0, 0)
    finalizer = solver.own._finalizer
    assert finalizer.alive
    del solver
    gc.collect()
    assert not finalizer.alive


class _MallInfo2(ctypes.Structure):
    _fields_ = [
        (name, ctypes.c_size_t)
        for name in ("arena", "ordblks", "smblks", "hblks", "hblkhd", "usmblks", "fsmblks", "uordblks", "fordblks")
    ] + [("keepcost", ctypes.c_size_t)]


def _heap_in_use() -> int:
    """Bytes of the C heap in use (glibc's ``mallinfo2``: allocated chunks, and mapped ones)."""
    libc = ctypes.CDLL(None)
    libc.mallinfo2.restype = _MallInfo2
    gc.collect()
    info = libc.mallinfo2()
    return int(info.uordblks + info.hblkhd)


@needs_binding
@pytest.mark.skipif(not hasattr(ctypes.CDLL(None), "mallinfo2"), reason="needs glibc's mallinfo2")
@pytest.mark.parametrize("name", ["cvode-bdf", "ida"])
def test_many_runs_do_not_grow_the_c_heap(name, case2):
    # A solver holds about 20 KB of SUNDIALS' memory (seen: 100 solvers kept, 2.1 MB), one N_Vector about
    # 600 B. Over 200 runs on one solver and 200 solvers made and freed (a setup each), the heap grew by
    # 2-19 KB in all (Python's and numpy's own caches); a leaked vector per run would add 120 KB, a leaked
    # solver 4 MB. Bound: 100 KB over each 200.
    from nsbench.hybrid.run import run_hybrid

    integ = nsbench.get_integrator(name)
    integ.setup(case2)
    twins = (case2, nsbench.get_problem("two-dof", case=2))
    for k in range(20):
        integ.setup(twins[k % 2])
        run_hybrid(twins[k % 2], integ, 20.0)
    before = _heap_in_use()
    for _ in range(200):
        raw = run_hybrid(twins[1], integ, 20.0)
    reused = _heap_in_use()
    for k in range(200):
        integ.setup(twins[k % 2])  # another problem: frees the solver; the run makes a new one
        raw = run_hybrid(twins[k % 2], integ, 20.0)
    renewed = _heap_in_use()
    assert raw.loop == "native" and raw.status.ok
    assert reused - before < 100_000
    assert renewed - reused < 100_000


# ---------------------------------------------------------------------- the compiled pieces
@needs_binding
def test_the_compiled_consistent_start_is_the_per_arc_one():
    # IDA's start at a switch, compiled for the loop, against the per-arc adapter's numpy function
    from nsbench.integrators import _sundials_native as native

    rng = np.random.default_rng(4)
    for case in (2, 4):
        problem = nsbench.get_problem("two-dof", case=case)
        p = np.array(problem.packed, dtype=float)
        for mode in ((0, 0), (1, 0), (0, -1), (-1, 1)):
            m = np.array(mode, dtype=np.int64)
            y, t = rng.normal(size=4), float(rng.uniform(0, 50))
            yy, yp, ident = np.zeros(6), np.zeros(6), np.zeros(6)
            native._consistent(p, m, t, y, yy, yp, ident)
            want_y, want_yp = sk.consistent_start(p, m, t, y)
            np.testing.assert_array_equal(yy, want_y)
            np.testing.assert_array_equal(yp, want_yp)
            algebraic = [4, 5] + [2 * i + 1 for i in range(2) if mode[i] == 0]
            assert [k for k in range(6) if ident[k] == 0.0] == sorted(algebraic)


@needs_binding
@pytest.mark.parametrize("kind", ["cvode", "ida"])
def test_the_roots_in_their_slots_are_the_per_arc_ones(kind):
    # the native root functions against the per-arc adapter's (numba) ones, value for value, for every mode of
    # a forced problem, with sections: the guards in their slots, 1.0 in the slots a mode leaves free
    from nsbench.integrators import _sundials_callbacks as cb
    from nsbench.integrators import _sundials_native as native

    problem = nsbench.get_problem("two-dof", case=2)
    solver = native.NativeSolver(native.CVODE if kind == "cvode" else native.IDA, problem, "BDF", 1e-8, 1e-10, 0.0, 2)
    ud, slots = solver.ud, problem.max_guards
    coeffs, levels = np.array([[0.0, 1.0, 0.0, 0.0], [0.3, 0.0, -1.0, 0.5]]), np.array([0.0, 0.2])
    rng = np.random.default_rng(7)
    for mode in ((0, 0), (1, 0), (0, -1), (-1, 1)):
        m = np.array(mode, dtype=np.int64)
        gk, gi, gs = (np.zeros(slots, np.int64) for _ in range(3))
        ng = int(problem.law.guards_of(problem.data.p, m, gk, gi, gs))
        arrays = (m, gk, gi, gs, coeffs, levels)
        for slot, a in zip((cb.UD_MODE, cb.UD_GK, cb.UD_GI, cb.UD_GS, cb.UD_SEC_C, cb.UD_SEC_L), arrays):
            ud[slot] = a.ctypes.data
        ud[cb.UD_NG], ud[cb.UD_NSEC] = ng, 2
        y = rng.normal(size=int(solver.bundle.h[native.H_NEQ]))
        out = np.full(slots + 2, np.nan)
        want = np.zeros(ng + 2)
        if kind == "cvode":
            cb.cvode_root_values(ud, y, out, True)
            sk.cvode_roots(solver.p, m, solver.fw[0], gk[:ng], gi[:ng], gs[:ng], coeffs, levels, y, want)
        else:
            cb.ida_root_values(ud, y, out, True)
            sk.ida_roots(solver.p, gk[:ng], gi[:ng], gs[:ng], coeffs, levels, y, want)
        np.testing.assert_array_equal(out[:ng], want[:ng])
        np.testing.assert_array_equal(out[ng:slots], 1.0)
        np.testing.assert_array_equal(out[slots:], want[ng:])
    solver.close()


def test_c_signatures_are_checked():
    with pytest.raises(ValueError, match="bad C signature"):
        capi.c_function("int CVode(void*)")

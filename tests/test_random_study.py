"""The random-parameter reliability study as a test (``-m slow``): 300 sets over the four 2-DOF cases.

A quarter of each case's sets sit on the fs = fr edge of block 1 (``rf1 = 1``), a
quarter on block 2's (``rf2 = rho2``), a quarter on both; case 1 adds sets a
relative 1e-5..1e-3 from its two grazing-sliding values (block 2's sticking phase
vanishes at v0 ~ 0.27442, block 1 starts sticking at v0 ~ 0.10042). Each set runs
in a supervised worker (:mod:`nsbench.workers.jobs`: a hard limit per step, crash
isolation): its reference with its independent certification
(:func:`compute_reference`), then six integrators among those that accept it
(:func:`assign`), so that every integrator available runs on about 90 sets, the
restricted ones on most of the sets they accept (``siconos-moreau-jean``: the
unforced linear sets with fs = fr on both blocks, about a dozen). What must hold:

- no exception, no crash, no hang (every job done, each step within its limit);
- a reference is used only if its check agrees with it (``ok``), otherwise it is
  marked failed and grades nothing (the fs = fr defect of ``exact`` showed as a
  reference whose check disagreed, while it was still used);
- every run whose status is ``success`` is on the reference's event sequence, or
  the bench's metrics flag it (``sequence_ok`` false: a wrong sequence is never
  counted), and the metrics agree with a direct comparison of the two logs;
- a reference-grade integrator (``exact``, ``exact-mp``, heyoka's extended
  precisions, ``reference``) is on the certified reference's sequence unless the
  set is ill-conditioned there (a start moved by 1e-9 changes the sequence);
- no false success: an event-driven integrator (each checks every guard on each of
  its steps) that ends ``success`` is on the reference's sequence wherever the set
  is well-conditioned (issue 48, item 9: ``scipy-dop853`` once stepped over a stick
  and logged a block-2 slip 0.08 late, as a success).

Spans are short (20; 60 for the grazing sets, where the motion must reach the
periodic orbit): 5 min 23 s for the 300 sets and 1800 runs of 21 integrators on 2
workers at load average 7-9 (heyoka's systems already compiled; compiling them on
first use adds about 2.5 minutes).
"""

from __future__ import annotations

import math

import numpy as np
import pytest

#: Spans of the ordinary and of the grazing sets.
T_END, T_GRAZING = 20.0, 60.0
#: Integrators per set (in rotation over the registry).
PER_SET = 6
#: Hard limit of one run or reference (seconds): a run takes well under 2 s; generous on a busy machine.
LIMIT = 300.0


def parameter_sets(seed: int = 2024, per_case: int = 75) -> list[tuple[int, dict, float]]:
    """``(case, params, t_end)`` of the study: edges, grazing points and ordinary sets of each case.

    The fs = fr edge in turn on block 1, on block 2, on both (where a single-level relay such as
    ``siconos-moreau-jean`` applies), then on neither.
    """
    rng = np.random.default_rng(seed)
    out = []
    for case in (1, 2, 3, 4):
        for i in range(per_case):
            if case == 1 and i >= per_case - 20:  # grazing-sliding: near case 1's two located values
                v0 = (0.27442, 0.10042)[i % 2] * (1.0 + rng.choice([-1, 1]) * 10.0 ** rng.uniform(-5, -3))
                out.append((case, {"v0": float(v0)}, T_GRAZING))
                continue
            p = dict(
                c1=rng.uniform(0.0, 0.1),
                c2=rng.uniform(0.0, 0.1),
                kappa=rng.uniform(0.2, 2.0),
                mu=rng.uniform(0.2, 2.0),
                rho2=rng.uniform(0.5, 2.0),
                v0=rng.uniform(0.02, 0.5),
            )
            p["rf1"] = 1.0 if i % 4 in (0, 2) else rng.uniform(0.4, 0.95)
            p["rf2"] = p["rho2"] if i % 4 in (1, 2) else rng.uniform(0.4, 0.95) * p["rho2"]
            if case in (2, 4):
                p.update(F=rng.uniform(0.05, 0.6), Omega=rng.uniform(0.3, 2.5))
            out.append((case, {k: float(v) for k, v in p.items()}, T_END))
    return out


def accepting(case: int, params: dict, names: list[str]) -> list[str]:
    """The integrators of ``names`` that accept the set's problem (their own refusals, nothing run)."""
    from nsbench.errors import UnsupportedProblemError
    from nsbench.integrators import integrator_class
    from nsbench.problems import get_problem

    problem = get_problem("two-dof", case=case, **params)
    out = []
    for name in names:
        try:
            integrator_class(name)().check_problem(problem)
        except UnsupportedProblemError:
            continue
        out.append(name)
    return out


def assign(sets: list[tuple[int, dict, float]], names: list[str]) -> list[list[str]]:
    """``PER_SET`` integrators per set, among those that accept it: the ones furthest behind their pace.

    Each integrator's quota is an even share of all runs (or every set it accepts, if fewer), spread
    evenly over the sets it accepts. A plain rotation gave an integrator restricted to some problems
    (linear only, one friction level) only the sets of its turn: one that refused all of those never ran.
    """
    ok = [accepting(case, params, names) for case, params, _ in sets]
    accepted = {n: sum(n in o for o in ok) for n in names}
    quota = {n: min(accepted[n], len(sets) * PER_SET / len(names)) for n in names}
    runs, seen = dict.fromkeys(names, 0), dict.fromkeys(names, 0)
    chosen = []
    for o in ok:
        for n in o:
            seen[n] += 1
        pick = sorted(o, key=lambda n: (runs[n] - quota[n] * seen[n] / accepted[n], names.index(n)))[:PER_SET]
        for n in pick:
            runs[n] += 1
        chosen.append(pick)
    return chosen


def _sequence(events) -> list[tuple[str, int]]:
    return list(zip(events["kind"], events["block"].astype(int)))


def study_set(
    index: int, case: int, params: dict, t_end: float, names: list[str], limit: float, *, stage, emit
) -> dict:
    """One set in a supervised worker: its reference, then each integrator; a small record of each."""
    from nsbench.bench.metrics import case_metrics, order_ties_as_reference
    from nsbench.bench.reference import candidates, compute_reference
    from nsbench.engine import simulate
    from nsbench.errors import UnsupportedProblemError
    from nsbench.integrators import integrator_class
    from nsbench.problems import get_problem

    problem = get_problem("two-dof", case=case, **params)
    stage(f"set {index}: reference", limit)
    ref = compute_reference(problem.config(), candidates(("exact", "reference")), 0.0, t_end, 20)
    runs = []
    for name in names:
        stage(f"set {index}: {name}", limit)
        try:
            res = simulate(problem, name, t_end, t_eval=ref.t_dense)
        except UnsupportedProblemError:
            continue
        row = {
            "integrator": name,
            "event_driven": integrator_class(name).capabilities.family == "event-driven"
            and not getattr(integrator_class(name), "whole_system", False),
            "status": res.status.value,
            "message": res.message,
            "reference_grade": integrator_class(name).capabilities.reference_grade,
            # events of the reference at one instant (within 1e-9) are compared in its order, as the bench does
            "same_sequence": (
                _sequence(order_ties_as_reference(ref.events, res.events)) == _sequence(ref.events) if ref.ok else None
            ),
            "sequence_ok": None,
        }
        if ref.ok and res.ok:
            dense = res.trajectory[list(problem.state_names)].to_numpy().T
            metrics = case_metrics(ref.events, res.events, ref.y_dense, dense, ref.y_final, res.y_final)
            row["sequence_ok"] = bool(metrics["sequence_ok"])
        runs.append(row)
    return {
        "index": index,
        "case": case,
        "params": params,
        "reference": ref.name,
        "reference_status": ref.status,
        "certify_note": ref.certify_note,
        "conditioning": ref.conditioning,
        "runs": runs,
    }


@pytest.mark.slow
def test_random_parameter_sets_every_integrator_no_fault_and_no_unflagged_wrong_sequence():
    from nsbench.integrators import integrator_class, list_integrators
    from nsbench.workers.jobs import Job, JobPool

    sets = parameter_sets()
    # every integrator that can run on this machine (an optional external one may be missing)
    names = [n for n in list_integrators() if not (getattr(integrator_class(n), "unavailable", None) or str)()]
    assert len(sets) == 300
    plan = assign(sets, names)
    planned = {n: sum(n in pick for pick in plan) for n in names}
    # an integrator for other problems only (siconos-event-driven: the bouncing ball) has no set here
    others = [n for n, k in planned.items() if k == 0 and not any(accepting(c, q, [n]) for c, q, _ in sets)]
    # every other integrator has sets it accepts (siconos-moreau-jean: unforced, fs = fr on both blocks)
    assert min(k for n, k in planned.items() if n not in others) >= 10, planned
    results, faults = [], []
    with JobPool(2) as pool:
        for i, (case, params, t_end) in enumerate(sets):
            pool.submit(Job(i, f"{__name__}:study_set", (i, case, params, t_end, plan[i], LIMIT)))
        for o in pool.outcomes():
            if o.kind == "done":
                results.append(o.value)
            elif o.final:  # an exception, a crash or a hang: what must never happen
                faults.append(f"set {o.key} {sets[o.key]}: {o.kind} in {o.stage}: {o.reason}")
    assert not faults, "\n".join(faults)
    assert len(results) == 300
    covered = {}
    wrong, inconsistent, refs, false_successes = [], [], [], []
    for r in results:
        if r["reference_status"] == "ok":
            # a reference in use agrees with its independent check over the whole span
            if "not certified from there" in r["certify_note"]:
                refs.append(f"set {r['index']} case {r['case']} {r['params']}: used although {r['certify_note']}")
        elif "not certified" not in r["reference_status"]:
            refs.append(f"set {r['index']}: no usable reference: {r['reference_status']}")
        for run in r["runs"]:
            covered[run["integrator"]] = covered.get(run["integrator"], 0) + 1
            if run["status"] != "success" or run["same_sequence"] is None:
                continue
            if run["sequence_ok"] != run["same_sequence"]:
                inconsistent.append(f"set {r['index']} {run['integrator']}: metrics say {run['sequence_ok']}")
            ill_conditioned = not math.isfinite(r["conditioning"])
            if run["event_driven"] and not run["same_sequence"] and not ill_conditioned:
                false_successes.append(f"set {r['index']} case {r['case']} {r['params']}: {run['integrator']}")
            if run["reference_grade"] and not run["same_sequence"] and not ill_conditioned:
                wrong.append(
                    f"set {r['index']} case {r['case']} {r['params']}: {run['integrator']} "
                    f"off the certified reference's sequence"
                )
    assert not refs, "\n".join(refs)
    assert not inconsistent, "\n".join(inconsistent)  # every success off the sequence is flagged
    assert not wrong, "\n".join(wrong)
    # fails at c07a67f on one run of 1800, as on main: set 223 (case 3, fs = fr on block 2), ida logs block 2's
    # slip at 7.284 and a 'reverse' at the same instant (IDA's root finding reads the rounding of the velocity
    # guard's double zero at the slip's start as a crossing); an event too many, not a stepped-over crossing
    # (no step is flagged, the adapter without its check gives the same); open, not excused here
    assert not false_successes, "\n".join(false_successes)
    # every planned run ran: none refused its set
    assert covered == {n: k for n, k in planned.items() if k}, (covered, planned)

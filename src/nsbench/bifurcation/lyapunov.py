"""Largest Lyapunov exponent of the mapping-point return map: an ensemble of Benettin estimates.

A mapping point is a slip event: the state where the locus of sticking phase
leaves a sliding region. The return map takes one mapping point to the next.
From a mapping point on the attractor, a copy is displaced by ``d0`` (in the
coordinates that are free there: velocities pinned at the belt speed are left
alone; for forced problems the forcing phase ``Omega t`` counts as a
coordinate), both are integrated to their next mapping point, the separation
``d`` is measured there, ``log(d / d0)`` is accumulated, and the copy is put
back at distance ``d0`` along the new separation (Benettin's two-trajectory
method). The mean of the logs is the exponent per mapping point; divided by
the elapsed time instead of the iteration count it is per unit time.

Why an ensemble. On a chaotic attractor the course of one trajectory depends on
the last bits of floating point (LAPACK kernels, CPU features), so one long
run gives a different estimate on another machine, and the error computed from
that run alone (block means of one correlated series) does not say by how
much. Here ``members`` independent estimates are made instead: each member
starts from its own seeded perturbation (size ``spread``) of the standard
initial condition, runs its own transient and its own Benettin iterations with
its own random initial direction. On a chaotic attractor the transient spreads
the members over the attractor (the perturbation grows by
``exp(exponent per unit time * transient)``), so their estimates are
independent draws of exactly the kind of variation another machine or another
start produces. The exponent is the ensemble mean, its standard error the
spread across members over ``sqrt(members)``, with a Student-t confidence
interval. What the ensemble cannot see is a bias common to all members (of
``d0``, of the integrator's discretisation, of the finite run length): compare
integrators or settings for that.

Members on another attractor. A member that disagrees with the others, both
statistically (leave-one-out t test, Bonferroni over the members) and by a
relevant amount (``> max(0.1 |exponent|, tol)``), did not sample the same
distribution: it ended on another attractor. This happens on the chaotic test
case (two-dof case 2, F = 0.1417): a coexisting stable motion (exponent about
-0.21 per mapping point) captures about one member in 100, mostly during its
transient from rest. A Lyapunov exponent belongs to an attractor, and the mean
of a mixture of attractors is the exponent of none, so such members are set
apart (``outliers``, each with its own estimate): ``exponent`` and its
uncertainty are those of the attractor the other members share, and
``exponent_all`` keeps the mean over every member for comparison.

Verdict (``converged``), see :func:`_verdict`: the standard error of the kept
members is small, ``<= max(0.05 |exponent|, tol / 2)``, and they are a clear
majority (at least :data:`MAJORITY` of the members finished): otherwise the
ensemble has no dominant attractor and no single exponent describes it.

The map is advanced by the engine (:func:`nsbench.engine.run`: the defaults and the
missed-crossing check of ``nsbench.simulate``), which starts in a given mode and stops
at the next slip event (a run that fails, a crossing stepped over among them, gives no
mapping point and ends the member with its reason); any registered
integrator runs there (``exact`` for linear problems and ``henon-rk4`` for any
are compiled end to end, the fastest).
"""

from __future__ import annotations

import math
import os
from dataclasses import dataclass, field
from typing import Hashable

import numpy as np

from nsbench.errors import ConfigError
from nsbench.status import OutcomeKind, Status

#: Family-wise false-alarm rate of the outlier test over all members.
OUTLIER_ALPHA = 1e-3
#: Share of the finished members that must share one attractor for a converged verdict.
MAJORITY = 0.75
#: Number of block means of the within-member standard error (a diagnostic).
N_BLOCKS = 10
#: Each member first advances a random number of mapping points in ``0 .. PHASES - 1``.
#: 60 is a multiple of every period up to 6 (and of 10, 12, 15, 20, 30).
PHASES = 60


@dataclass
class LyapunovResult:
    """Ensemble estimate of the largest Lyapunov exponent of the mapping-point return map.

    Attributes
    ----------
    exponent
        Mean of the estimates of the members that share one attractor (every
        finished member but the ``outliers``), per mapping point.
    standard_error
        Standard deviation of those members' estimates over the square root of
        their number: the uncertainty of ``exponent`` against another start or
        another machine.
    exponent_all, standard_error_all
        The same over every finished member, outliers included (a mixture of
        attractors when there are outliers).
    ci_low, ci_high, confidence
        Student-t confidence interval of ``exponent`` (the kept members' number
        less one degrees of freedom) at level ``confidence``.
    exponent_per_time, standard_error_per_time
        The same per unit time (each member: sum of logs over its elapsed time).
    members
        Each member's estimate per mapping point (mean of its ``log(d_k / d0)``);
        NaN for a member that failed.
    members_per_time
        Each member's estimate per unit time.
    member_errors
        Each member's standard error from its own 10 block means: a diagnostic
        only (one correlated series understates what another start gives).
    converged
        The run succeeded, ``precise``, and the kept members are at least
        :data:`MAJORITY` of the finished ones.
    precise
        ``standard_error <= max(0.05 |exponent|, tol / 2)``.
    outliers
        Indices of members that disagree with the others (see :func:`_verdict`):
        on another attractor; left out of ``exponent``. ``consistent`` is ``not outliers``.
    iterations, iterations_per_member
        Map iterations done in all and by each member.
    mean_return_time
        Mean time between mapping points over all members.
    block_mismatches
        Iterations where the two copies reached their next mapping point on
        different blocks (near a border-collision), over all members.
    seed
        Seed of the members' start perturbations, phases and initial directions
        (member ``i`` draws from child ``i`` of ``SeedSequence(seed)``, whatever
        the number of members or workers).
    logs
        ``log(d_k / d0)``, one row per member (NaN after a member's failure).
    """

    exponent: float
    standard_error: float
    exponent_all: float
    standard_error_all: float
    ci_low: float
    ci_high: float
    confidence: float
    exponent_per_time: float
    standard_error_per_time: float
    members: np.ndarray
    members_per_time: np.ndarray
    member_errors: np.ndarray
    converged: bool
    precise: bool
    outliers: tuple[int, ...]
    iterations: int
    iterations_per_member: int
    mean_return_time: float
    block_mismatches: int
    seed: int
    status: str = Status.SUCCESS.value
    message: str = ""
    logs: np.ndarray = field(default_factory=lambda: np.empty((0, 0)), repr=False)

    @property
    def consistent(self) -> bool:
        """No member is an outlier from the others (all on one attractor)."""
        return not self.outliers

    @property
    def n_kept(self) -> int:
        """Finished members that share the attractor of ``exponent``."""
        return int(np.isfinite(self.members).sum()) - len(self.outliers)

    @property
    def majority(self) -> bool:
        """The kept members are a clear majority of the finished ones (see :data:`MAJORITY`)."""
        return _holds_majority(self.n_kept, self.n_kept + len(self.outliers))

    @property
    def n_members(self) -> int:
        """Members run (including any that failed)."""
        return len(self.members)

    def summary(self) -> str:
        """One line with the estimate, its uncertainty, the verdict and how it was made."""
        if self.converged:
            verdict = "converged"
        else:
            why = []
            if self.status != Status.SUCCESS:
                why.append(self.status)
            if not self.precise:
                why.append("standard error too large")
            if not self.majority:
                why.append("no attractor holds a clear majority of the members")
            verdict = "NOT converged: " + "; ".join(why)
        if self.outliers:
            verdict += (
                f"; over {self.n_kept} members: {len(self.outliers)} other(s) ended on another "
                "attractor, set apart: "
                + ", ".join(f"member {i} {self.members[i]:+.4f}" for i in self.outliers)
                + f"; mean over all members {self.exponent_all:+.5f}"
            )
        spread = (
            f"members {np.nanmin(self.members):+.4f} .. {np.nanmax(self.members):+.4f}"
            if np.isfinite(self.members).any()
            else "no member finished"
        )
        return (
            f"largest Lyapunov exponent {self.exponent:+.5f} per mapping point, standard error "
            f"{self.standard_error:.2g}, {100 * self.confidence:g}% CI [{self.ci_low:+.5f}, "
            f"{self.ci_high:+.5f}]; {self.exponent_per_time:+.5f} per unit time (standard error "
            f"{self.standard_error_per_time:.2g}) ({verdict}; {self.n_members} members x "
            f"{self.iterations_per_member} iterations, {spread}, seed {self.seed}, "
            f"mean return time {self.mean_return_time:.4g}, block mismatches {self.block_mismatches})"
        )


@dataclass
class _Member:
    """One member's run: its logs, the times of its mapping points, and how it ended."""

    logs: np.ndarray
    times: np.ndarray
    t_first: float
    mismatches: int
    message: str = ""


# -- one step of the return map ------------------------------------------------------------------


def _mapping_point(integ, problem, t, y, mode, t_rec, window):
    """First mapping point at or after ``t_rec`` of the motion from ``(t, y)``.

    ``mode`` is the mode at the start (None: the mode of ``y``). Returns
    ``((t, y, mode, block), status)``, or ``(None, status)`` if there is none
    before ``t_rec + window``. The hybrid core stops right after the settle step
    of that slip event, so the returned state and mode are the ones to continue from.
    """
    from nsbench.engine import run
    from nsbench.problems.modes import EVENT_KINDS

    raw = run(problem, integ, t_rec + window, t0=t, y0=y, mode=mode, record_from=t_rec, stop_kind="slip", stop_count=1)
    slips = np.flatnonzero(raw.events.kind == EVENT_KINDS.index("slip"))
    if not raw.status.ok or not raw.stopped or slips.size == 0:  # a failed run (a crossing missed) is no point
        return None, raw.status.value if raw.status.ok else f"{raw.status.value}: {raw.message}"
    block = int(raw.events.block[slips[0]])
    return (raw.t, raw.y.copy(), np.array(raw.mode, dtype=np.int64), block), raw.status.value


# -- one member ----------------------------------------------------------------------------------


def _free_direction(vec, y, problem, forced):
    """``vec`` with the pinned coordinates zeroed, normalised; None if nothing is left."""
    vec = vec.copy()
    v0 = problem.v0
    pinned = [2 * i + 1 for i in range(problem.n_blocks) if y[2 * i + 1] == v0]
    vec[pinned] = 0.0
    if not forced:
        vec[problem.n_states] = 0.0
    norm = math.sqrt(float(vec @ vec))
    return vec / norm if norm > 0 else None


def _run_member(integ, problem, rng, iterations, transient, window, d0, spread, align) -> _Member:
    """Benettin iterations of one member from its own perturbed start.

    After the transient the member advances a random number of mapping points
    (uniform in ``0 .. PHASES - 1``), so that members on one periodic orbit start
    at different points of it: the error of averaging over a fraction of a
    period then differs between members and shows in their spread (it averages
    out over the phases), instead of being the same for all and invisible. In
    case 1, v0 = 0.1 (period 3, exponent -0.1251), 25 iterations from one fixed
    phase give -0.1069 in every member.

    The first ``align`` Benettin iterations are not counted: the random initial
    direction is not yet the most expanding one, and its first stretch is
    atypical (measured in case 2, F = 0.1417: +0.93 +- 0.16 on the first
    iteration against +0.08 on average, indistinguishable from it afterwards).
    """
    forced = problem.is_forced and problem.forcing_frequency > 0
    w = problem.forcing_frequency if forced else 0.0
    n = problem.n_states
    y0 = problem.initial_state() + spread * rng.normal(size=n)
    ref, status = _mapping_point(integ, problem, 0.0, y0, None, transient, window)
    for _ in range(int(rng.integers(PHASES))):
        if ref is None:
            break
        ref, status = _mapping_point(integ, problem, ref[0], ref[1], ref[2], ref[0], window)
    if ref is None:
        return _Member(
            np.empty(0),
            np.empty(0),
            0.0,
            0,
            f"no mapping point within {window:g} after the transient ({status}): "
            "the motion has no slip events (pure sliding or permanent sticking)",
        )
    u = _free_direction(rng.normal(size=n + 1), ref[1], problem, forced)
    logs: list[float] = []
    times: list[float] = []
    mismatches = 0
    t_first = ref[0]
    for k in range(align + iterations):
        if k == align:  # the direction has aligned: count from here
            logs, times, mismatches, t_first = [], [], 0, ref[0]
        if u is None:  # every free direction collapsed: restart from a random one
            u = _free_direction(rng.normal(size=n + 1), ref[1], problem, forced)
        t, y, mode, _ = ref
        pert_y = y + d0 * u[:n]
        pert_t = t + d0 * u[n] / w if forced else t
        nxt, status = _mapping_point(integ, problem, t, y, mode, t, window)
        pnx, pstatus = (
            (None, "") if nxt is None else _mapping_point(integ, problem, pert_t, pert_y, mode.copy(), pert_t, window)
        )
        if nxt is None or pnx is None:
            return _Member(
                np.array(logs),
                np.array(times),
                t_first,
                mismatches,
                f"no next mapping point within {window:g} ({status if nxt is None else pstatus})",
            )
        mismatches += int(nxt[3] != pnx[3])
        diff = np.append(pnx[1] - nxt[1], w * (pnx[0] - nxt[0]))
        d = math.sqrt(float(diff @ diff))
        # a vanishing separation (both copies stuck to the same state) is a strong contraction:
        # count it as a factor 1e-16 rather than log(0)
        logs.append(math.log(max(d, d0 * 1e-16) / d0))
        times.append(nxt[0])
        ref = nxt
        u = _free_direction(diff, nxt[1], problem, forced) if d > 0 else None
    return _Member(np.array(logs), np.array(times), t_first, mismatches)


# -- running the members, in this process or in supervised workers --------------------------------

#: Default hard limit of one member's run in a worker (seconds; compilation from a cold cache included).
MEMBER_LIMIT = 1800.0
#: Per worker process: the integrator set up for the last problem (compiled code loaded).
_WORKER_STATE: dict = {}


def member_job(
    problem,
    integrator: str,
    options: dict,
    index: int,
    seed_seq: np.random.SeedSequence,
    params: dict,
    limit: float | None,
    *,
    stage,
    emit,
) -> _Member:
    """Member ``index`` in a supervised worker (:mod:`nsbench.workers.jobs`), the integrator set up once per worker."""
    from nsbench.integrators import get_integrator

    key = repr((problem, integrator, sorted(options.items())))
    if _WORKER_STATE.get("key") != key:
        stage("integrator set-up", limit)
        integ = get_integrator(integrator, **options)
        integ.setup(problem)
        _WORKER_STATE.update(key=key, integ=integ)
    stage(f"member {index}", limit)
    return _run_member(_WORKER_STATE["integ"], problem, np.random.default_rng(seed_seq), **params)


def _lost_member(reason: str) -> _Member:
    return _Member(np.empty(0), np.empty(0), math.nan, 0, reason)


def _run_members(integ, problem, integrator, options, seeds, params, workers, limit, log_path=None) -> list[_Member]:
    if workers == 0:
        return [_run_member(integ, problem, np.random.default_rng(s), **params) for s in seeds]
    from nsbench.workers.jobs import Job, JobPool, WorkerLog

    done: dict[Hashable, _Member] = {}  # by job key: the member's index
    log = WorkerLog(log_path, f"the Lyapunov members with {integrator}")
    with JobPool(min(workers, len(seeds))) as pool:
        for i, s in enumerate(seeds):
            pool.submit(Job(i, f"{__name__}:member_job", (problem, integrator, options, i, s, params, limit)))
        for o in pool.outcomes():
            if o.kind is OutcomeKind.DONE:
                done[o.key] = o.value
            elif o.final:  # time limit, crash, or an exception the member did not turn into a message
                done[o.key] = _lost_member(f"{o.kind}: {o.reason}")
                log.add(f"member {o.key} ({o.stage or 'start'})", o.reason, o.detail)
    log.report()
    return [done[i] for i in range(len(seeds))]


# -- public entry point --------------------------------------------------------------------------


def largest_exponent(
    problem,
    integrator: str | None = None,
    *,
    options: dict | None = None,
    transient: float = 1000.0,
    iterations: int = 10000,
    members: int = 32,
    d0: float = 1e-8,
    window: float = 2000.0,
    seed: int = 0,
    spread: float = 1e-3,
    align: int = 10,
    tol: float = 0.01,
    confidence: float = 0.95,
    workers: int = 1,
    member_limit: float | None = MEMBER_LIMIT,
    worker_log: str | os.PathLike | None = None,
) -> LyapunovResult:
    """Ensemble Benettin estimate of the largest Lyapunov exponent of the mapping points of ``problem``.

    Parameters
    ----------
    problem
        The oscillator (any problem the integrator accepts).
    integrator
        Registered integrator; default ``exact`` for linear problems,
        ``henon-rk4`` otherwise (both compiled end to end through the core;
        any other integrator runs too, arc by arc).
    options
        Options of the integrator (e.g. ``{"h": 0.01}`` for ``henon-rk4``).
    transient
        Time each member integrates from its start before its first mapping point used.
    iterations
        Return-map iterations in all, split evenly over the members
        (``iterations // members`` each, at least 20).
    members
        Independent estimates (at least 4): the spread across them gives the
        standard error. Many short members beat a few long ones when a member
        can fall onto another attractor (see the module notes): such a member is
        set apart, and the many others still give the estimate.
    d0
        Separation the copy is renormalised to at each mapping point.
    window
        Longest time allowed between two mapping points.
    seed
        Seed of the members' start perturbations and initial directions.
    spread
        Standard deviation of each member's random perturbation of every
        coordinate of the standard initial condition (rest at the origin).
    align
        Iterations each member runs before counting, so that its random initial
        direction aligns with the most expanding one (not part of ``iterations``).
    tol
        Absolute tolerance of the verdict (see :func:`_verdict`).
    confidence
        Level of the Student-t confidence interval.
    workers
        Supervised worker processes running members at once; ``0`` runs them
        in this process, without hard limits. The result does not depend on it.
    member_limit
        Hard limit in seconds of one member's run in a worker (``None``: none):
        past it the worker is ended and the member counts as failed, with the
        reason; the other members go on. A crashed worker costs only its member.
    worker_log
        File the tracebacks of members that raised are appended to (default: a new
        temporary file); one line on stderr names it. Nothing is printed by the workers.

    Returns
    -------
    LyapunovResult
        Per-member and ensemble estimates, uncertainty and verdict; status
        ``failure`` with a message if a member found no next mapping point.
    """
    from nsbench.integrators import get_integrator

    _check(iterations, members, d0, transient, window, spread, align, tol, confidence, workers, seed)
    from nsbench.workers.jobs import check_limit

    check_limit("member_limit", member_limit)
    if integrator is None:
        integrator = "exact" if problem.is_linear else "henon-rk4"
    if "slip" not in problem.event_kinds:  # not once per member
        raise ConfigError(
            f"the exponent is measured between mapping points (slip events); {problem.name} has none "
            f"(its event kinds: {', '.join(problem.event_kinds)})"
        )
    integ = get_integrator(integrator, **(options or {}))
    from nsbench.integrators.base import require_event_driven

    require_event_driven(integ, "a Lyapunov exponent")  # not once per member
    if workers == 0:
        integ.setup(problem)  # the members run here
    else:  # set up in the workers, under member_limit: a plug-in's setup that hangs costs its members
        from nsbench.bifurcation.sweep import check_in_caller

        check_in_caller(integ, problem, "a Lyapunov exponent")
    members, per_member = int(members), int(iterations // members)
    seeds = np.random.SeedSequence(int(seed)).spawn(members)
    params = dict(iterations=per_member, transient=transient, window=window, d0=d0, spread=spread, align=int(align))
    runs = _run_members(
        integ, problem, integrator, dict(options or {}), seeds, params, workers, member_limit, worker_log
    )
    return _result(runs, per_member, int(seed), tol, confidence)


def _is_int(x) -> bool:
    return isinstance(x, (int, np.integer)) or (isinstance(x, float) and x.is_integer())


def _check(iterations, members, d0, transient, window, spread, align, tol, confidence, workers, seed) -> None:
    if not _is_int(members) or members < 4:
        raise ConfigError(
            f"members = {members!r} must be an integer of at least 4 (the standard error comes from their spread)"
        )
    if not _is_int(iterations) or iterations // members < 20:
        raise ConfigError(
            f"iterations = {iterations!r} must be an integer of at least 20 per member "
            f"({20 * members} for {members} members)"
        )
    if not (0.0 < d0 < 1e-2):
        raise ConfigError(f"d0 = {d0!r} must be in (0, 0.01)")
    if not (transient >= 0.0 and math.isfinite(transient)):
        raise ConfigError(f"transient = {transient!r} must be finite and >= 0")
    if not (window > 0.0 and math.isfinite(window)):
        raise ConfigError(f"window = {window!r} must be finite and > 0")
    if not (0.0 < spread < 1.0):
        raise ConfigError(f"spread = {spread!r} must be in (0, 1)")
    if not _is_int(align) or align < 0:
        raise ConfigError(f"align = {align!r} must be an integer >= 0")
    if not (tol > 0.0):
        raise ConfigError(f"tol = {tol!r} must be > 0")
    if not (0.0 < confidence < 1.0):
        raise ConfigError(f"confidence = {confidence!r} must be in (0, 1)")
    if not _is_int(workers) or workers < 0:
        raise ConfigError(f"workers = {workers!r} must be an integer >= 0 (0: in this process)")
    if not _is_int(seed) or seed < 0:
        raise ConfigError(f"seed = {seed!r} must be an integer >= 0")


# -- statistics ----------------------------------------------------------------------------------


def _block_error(logs: np.ndarray) -> float:
    """Standard error of the mean of one correlated series from ``N_BLOCKS`` block means."""
    k = len(logs) // N_BLOCKS * N_BLOCKS
    if k < 2 * N_BLOCKS:
        return np.nan
    blocks = logs[:k].reshape(N_BLOCKS, -1).mean(axis=1)
    return float(blocks.std(ddof=1) / math.sqrt(N_BLOCKS))


def _mean_and_error(values: np.ndarray) -> tuple[float, float]:
    k = len(values)
    if k == 0:
        return np.nan, np.nan
    mean = float(values.mean())
    return mean, float(values.std(ddof=1) / math.sqrt(k)) if k >= 2 else np.nan


def _outliers(values: np.ndarray, relevant: float, alpha: float = OUTLIER_ALPHA) -> tuple[int, ...]:
    """Members that disagree with the others, statistically and by more than ``relevant``.

    For member ``i`` with the others' mean ``m`` and standard deviation ``s``
    (``K - 1`` values), ``(x_i - m) / (s sqrt(1 + 1/(K-1)))`` follows Student's
    t with ``K - 2`` degrees of freedom when all members are independent normal
    draws of one distribution (the externally studentised residual). A member is
    flagged when this exceeds the two-sided ``alpha / K`` quantile (Bonferroni:
    at most ``alpha`` false alarms over the whole ensemble) and
    ``|x_i - m| > relevant``: members of a periodic orbit agree to rounding, so
    a tiny spread would make harmless differences "significant".
    """
    from scipy.stats import t as student

    k = len(values)
    if k < 3:
        return ()
    limit = float(student.ppf(1.0 - alpha / (2 * k), k - 2))
    flagged = []
    for i in range(k):
        others = np.delete(values, i)
        dev = abs(float(values[i] - others.mean()))
        scale = float(others.std(ddof=1)) * math.sqrt(1.0 + 1.0 / (k - 1))
        if dev > relevant and (scale == 0.0 or dev / scale > limit):
            flagged.append(i)
    return tuple(flagged)


def _holds_majority(n_kept: int, n_finished: int) -> bool:
    """Whether ``n_kept`` members on one attractor are at least :data:`MAJORITY` of ``n_finished``."""
    return n_kept >= MAJORITY * n_finished


def _verdict(values: np.ndarray, tol: float) -> tuple[float, float, bool, tuple[int, ...]]:
    """Mean, standard error and precision of the members' ``values`` but the outliers; the outliers.

    Outliers: :func:`_outliers` with relevance ``max(0.1 |mean of all|, tol)``:
    members on another attractor, left out of the mean and its standard error.
    ``precise``: standard error ``<= max(0.05 |mean|, tol / 2)`` (5 % relative,
    or an absolute floor near zero, where a relative rule cannot be met).
    """
    mean_all, _ = _mean_and_error(values)
    outliers = _outliers(values, max(0.1 * abs(mean_all), tol)) if np.isfinite(mean_all) else ()
    mean, se = _mean_and_error(np.delete(values, list(outliers)))
    precise = bool(np.isfinite(se) and se <= max(0.05 * abs(mean), tol / 2))
    return mean, se, precise, outliers


def _result(runs: list[_Member], per_member: int, seed: int, tol: float, confidence: float) -> LyapunovResult:
    """Ensemble statistics of the members; a failed member is NaN and makes the status ``failure``."""
    from scipy.stats import t as student

    ok = np.array([not r.message for r in runs])
    lam = np.array([r.logs.mean() if k else np.nan for r, k in zip(runs, ok)])
    per_time = np.array([r.logs.sum() / (r.times[-1] - r.t_first) if k else np.nan for r, k in zip(runs, ok)])
    index = np.flatnonzero(ok)
    mean, se, precise, outliers = _verdict(lam[ok], tol)
    mean_all, se_all = _mean_and_error(lam[ok])
    outliers = tuple(int(index[j]) for j in outliers)
    kept = ok.copy()
    kept[list(outliers)] = False
    mean_t, se_t = _mean_and_error(per_time[kept])
    n_kept = int(kept.sum())
    half = float(student.ppf(0.5 + confidence / 2, n_kept - 1)) * se if n_kept >= 2 else np.nan
    logs = np.full((len(runs), per_member), np.nan)
    for row, r in zip(logs, runs):
        row[: len(r.logs)] = r.logs
    n_done = sum(len(r.logs) for r in runs)
    total_time = float(sum(r.times[-1] - r.t_first for r in runs if len(r.times)))
    failed = [f"member {i}: {r.message}" for i, r in enumerate(runs) if r.message]
    return LyapunovResult(
        exponent=mean,
        standard_error=se,
        exponent_all=mean_all,
        standard_error_all=se_all,
        ci_low=mean - half,
        ci_high=mean + half,
        confidence=confidence,
        exponent_per_time=mean_t,
        standard_error_per_time=se_t,
        members=lam,
        members_per_time=per_time,
        member_errors=np.array([_block_error(r.logs) if k else np.nan for r, k in zip(runs, ok)]),
        converged=bool(not failed and precise and _holds_majority(n_kept, int(ok.sum()))),
        precise=precise,
        outliers=outliers,
        iterations=n_done,
        iterations_per_member=per_member,
        mean_return_time=total_time / n_done if n_done else np.nan,
        block_mismatches=sum(r.mismatches for r in runs),
        seed=seed,
        status=(Status.ERROR if failed else Status.SUCCESS).value,
        message="; ".join(failed),
        logs=logs,
    )
